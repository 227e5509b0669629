"""Command-line interface: a thin layer over the Python API.

Each sub-command parses its options, calls the API and reports. A ``ValueError`` (bad input)
becomes its message on stderr and exit code 2; any other failure during the work exits 1.
"""

from __future__ import annotations

import argparse
import logging
import sys


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="shellbuckle",
        description="Buckling of thin elastic spherical shells under volume loss.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for register in _COMMANDS:
        register(sub)
    return parser


# Each entry adds one sub-command: register(subparsers) -> sets ``func`` via set_defaults.
_COMMANDS: list = []


def main(argv=None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"shellbuckle {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"shellbuckle {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a failure during the work, not bad input
        logging.getLogger("shellbuckle").debug("failure", exc_info=True)
        print(f"shellbuckle {args.command}: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
