"""The ``gmsfric`` command line.

Each subcommand lives in its own module exposing ``register(subparsers)``; the module adds its
parser and sets ``func`` (called with the parsed arguments, returning an exit code).  Adding a
command = adding its module name to ``COMMAND_MODULES``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Sequence

from .errors import GmsfricError

COMMAND_MODULES = [
    "gmsfric.identify.cli", "gmsfric.identify.paper",
    "gmsfric.demo",
    "gmsfric.loop.cli",
    "gmsfric.glitch.cli",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gmsfric", description="Friction identification and fast simulation of precision servo axes.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from . import __version__

        print(__version__)
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except GmsfricError as exc:
        print(f"gmsfric {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
