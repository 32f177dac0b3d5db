"""Floor 13, the ``mjx-balance`` command line: the top layer, which nothing in the library
imports; one module per command, each with ``add_parser(sub)`` and its command function(s).
docs/architecture.md, "The modules", maps its modules; the README's "Commands" lists the
commands.

simulate, sweep and table are thin layers over the Python API (``mjx_balance.api``): they
resolve their options into its arguments, then write figures and print.

Conventions: ``python -m mjx_balance`` is ``mjx-balance``; ``--version`` prints the package's,
JAX's, jaxlib's and MuJoCo's versions; messages and progress go through ``logging`` (logger
``mjx_balance``: information on stdout, warnings and errors on stderr; ``-q`` keeps only
warnings and errors and turns progress bars off, ``-v`` adds debug messages); ``--help`` shows
every default; ``--set SECTION.KEY=VALUE`` overrides the configuration of any command that
takes ``--config``; ``--no-cache`` turns JAX's persistent compilation cache off
(``mjx_balance.runtime.cache``).

Building the parser imports every command module, none of which loads the library at import:
each command imports it when it runs (after :func:`main.use_host_cores`, which must see JAX
not yet imported), so ``--help`` loads neither JAX, MuJoCo nor pandas.

Exit codes: 0 success, 1 failure during the work, 2 bad usage. Bad arguments end in one line on
stderr and exit code 2, before any work and before anything is written: values and paths are
checked by the argparse types of ``options.py`` (argparse prints its usage, then
``mjx-balance CMD: error: argument --X: ...``), a configuration that breaks a rule by
``params`` (ParameterError: ``mjx-balance: error: ...``). An OSError during the work (a place
that passed the checks but refuses the write, a full disk) is a failure: one line, exit code 1.
"""

from .main import console, main

__all__ = ["console", "main"]
