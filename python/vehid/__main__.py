"""``python -m vehid``: the same command line as the ``vehid`` script."""

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
