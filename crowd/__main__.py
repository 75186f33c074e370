"""``python -m crowd``: the same as the ``crowd`` console script."""
import sys

from crowd.cli import main

sys.exit(main())
