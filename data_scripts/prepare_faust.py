"""Thin command-line wrapper of :mod:`prodmaps.prepare.faust` (see its docstring for usage).

    python data_scripts/prepare_faust.py --help
"""

import sys

from prodmaps.prepare.archive import run_cli
from prodmaps.prepare.faust import main

if __name__ == "__main__":
    sys.exit(run_cli(main))
