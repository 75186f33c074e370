"""``python -m crowd``: the same as the ``crowd`` console script."""
import sys

from crowd.cli import main

if __name__ == "__main__":  # dask / multiprocessing workers may import this module
    sys.exit(main())
