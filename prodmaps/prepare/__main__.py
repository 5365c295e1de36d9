"""``python -m prodmaps.prepare faust|tosca|variants [options]``."""

import importlib
import sys

from .archive import run_cli

USAGE = "usage: python -m prodmaps.prepare {faust,tosca,variants} [options]  (--help for each)"


def main(argv=None) -> int:
    """Run ``python -m prodmaps.prepare faust|tosca|variants [options]``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] in (["-h"], ["--help"]):
        print(USAGE + "\n\n"
              "  faust     MPI-FAUST training registrations (or any subset) from your own download\n"
              "  tosca     TOSCA high-resolution from your own download\n"
              "  variants  remeshed variants of a prepared dataset's shapes, with their ground truth")
        return 0
    if not argv or argv[0] not in ("faust", "tosca", "variants"):
        print(USAGE, file=sys.stderr)
        return 2
    return run_cli(importlib.import_module(f"prodmaps.prepare.{argv[0]}").main, argv[1:])


if __name__ == "__main__":
    sys.exit(main())
