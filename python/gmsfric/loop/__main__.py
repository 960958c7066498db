"""``python -m gmsfric.loop ...`` runs ``gmsfric loop ...`` (same arguments)."""

import argparse
import sys

from ..errors import GmsfricError
from .cli import register


def _main() -> int:
    parser = argparse.ArgumentParser(prog="gmsfric")
    sub = parser.add_subparsers(dest="command")
    register(sub)
    args = parser.parse_args(["loop", *sys.argv[1:]])
    try:
        return int(args.func(args) or 0)
    except GmsfricError as exc:
        print(f"gmsfric loop: error: {exc}", file=sys.stderr)
        return 2


sys.exit(_main())
