"""Command-line interface: a thin layer over the Python API.

Every sub-command is one module of :mod:`shellbuckle.commands` (``register(subparsers)`` adds
it and sets its ``func``), found at start-up; the options several commands share are declared
once in :mod:`shellbuckle.commands._options`. :func:`main` runs the command and keeps the exit
codes: 0 on success, 2 on bad input (a ``ValueError`` or ``FileNotFoundError``: its message on
stderr), 130 when interrupted, 1 on any other failure during the work.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys


def command_modules() -> list:
    """The modules of :mod:`shellbuckle.commands` that define a sub-command, by name (those
    whose name starts with ``_`` hold shared helpers)."""
    from . import commands

    names = sorted(info.name for info in pkgutil.iter_modules(commands.__path__)
                   if not info.name.startswith("_"))
    return [importlib.import_module(f"{commands.__name__}.{name}") for name in names]


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="shellbuckle",
        description="Buckling of thin elastic spherical shells under volume loss.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in command_modules():
        module.register(sub)
    return parser




def main(argv=None) -> int:
    parser = build_parser()
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
