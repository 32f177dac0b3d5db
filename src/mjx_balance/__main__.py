"""``python -m mjx_balance``: the ``mjx-balance`` command line."""

if __name__ == "__main__":  # imported as a module (pkgutil.walk_packages), it imports nothing
    from .cli import console

    console()
