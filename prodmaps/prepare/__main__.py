"""``python -m prodmaps.prepare faust|tosca|faust_r|tosca_r|tosca_r_noniso|variants [options]``."""

import importlib
import sys

from .archive import run_cli

COMMANDS = {
    "faust": "MPI-FAUST training registrations (or any subset) from your own download",
    "tosca": "TOSCA high-resolution from your own download",
    "faust_r": "FAUST_r: the 100 FAUST shapes remeshed (~5k vertices), from a clone of "
               "github.com/llorz/SGA18_orientation_BCICP_dataset (or its zip)",
    "tosca_r": "TOSCA_r: 76 remeshed TOSCA shapes in 8 classes, from the same clone",
    "tosca_r_noniso": "TOSCA_r non-isometric: 24 remeshed shapes (gorilla, man, woman), from the same clone",
    "variants": "remeshed variants of a prepared dataset's shapes, with their ground truth",
}
USAGE = f"usage: python -m prodmaps.prepare {{{','.join(COMMANDS)}}} [options]  (--help for each)"


def main(argv=None) -> int:
    """Run ``python -m prodmaps.prepare <command> [options]``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] in (["-h"], ["--help"]):
        print(USAGE + "\n\n" + "\n".join(f"  {name:<15} {text}" for name, text in COMMANDS.items()))
        return 0
    if not argv or argv[0] not in COMMANDS:
        print(USAGE, file=sys.stderr)
        return 2
    if argv[0] in ("faust_r", "tosca_r", "tosca_r_noniso"):
        return run_cli(importlib.import_module("prodmaps.prepare.sga18").MAINS[argv[0]], argv[1:])
    return run_cli(importlib.import_module(f"prodmaps.prepare.{argv[0]}").main, argv[1:])


if __name__ == "__main__":
    sys.exit(main())
