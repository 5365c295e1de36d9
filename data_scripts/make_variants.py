"""Thin command-line wrapper of :mod:`prodmaps.prepare.variants` (see its docstring for usage).

    python data_scripts/make_variants.py --help
"""

import sys

from prodmaps.prepare.archive import run_cli
from prodmaps.prepare.variants import main

if __name__ == "__main__":
    sys.exit(run_cli(main))
