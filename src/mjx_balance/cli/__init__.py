"""The ``mjx-balance`` command line: the top layer, which nothing in the library imports.

    main.py         main(argv), build_parser() (each command module's add_parser), logging,
                    --version, use_host_cores; exit codes 0 success, 1 failure during the
                    work, 2 bad usage
    options.py      argument types (finite_float, out_folder, ...), HelpFormatter, EPILOG and
                    the flags several commands share (common_options, engine_options, ...)
    common.py       what the commands share when they run: the run's configuration, one push,
                    progress, the physics path, the work in an output folder under its lock

One module per command, each with ``add_parser(sub)`` and its command function(s):

    simulate.py     simulate       scalar MuJoCo C + OSQP, one scenario at a time
    bench.py        bench          whole closed loop: MJX + ADMM vs reference vs IPOPT
                    bench solver   batched ADMM vs OSQP vs CasADi/IPOPT
                    bench physics  where the time goes; MJX vs MuJoCo C
    sweep.py        sweep          force x duration region map (MJX + ADMM)
                    table          max acting time per force (batched bisection)
    compare.py      compare        several configurations on one grid
    landscape.py    landscape      area, sustained limit, energy over Q x R scales
    basin.py        basin          recovery basin over initial CoM states
    sensitivity.py  sensitivity    the table under every reading of the study
    animate.py      animate        stick-figure GIF of one push (reference)
    report.py       report         HTML report: the study's experiments and studies
    explore.py      explore        a local page: every cell of a folder's map opens its run
    model.py        model          the MJCF of the configured body
                    view           one push replayed in MuJoCo's passive viewer

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
