"""``python -m prodmaps.prepare faust|tosca|variants [options]``."""

import sys

from .archive import run_cli


def main(argv=None) -> int:
    """Run ``python -m prodmaps.prepare faust|tosca|variants [options]``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    commands = {"faust": "faust", "tosca": "tosca", "variants": "variants"}
    if not argv or argv[0] not in commands:
        print("usage: python -m prodmaps.prepare {faust,tosca,variants} [options]  (--help for each)", file=sys.stderr)
        return 2
    import importlib

    module = importlib.import_module(f"prodmaps.prepare.{commands[argv[0]]}")
    return run_cli(module.main, argv[1:])


if __name__ == "__main__":
    sys.exit(main())
