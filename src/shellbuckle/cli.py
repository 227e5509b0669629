"""Command-line interface: a thin layer over the Python API.

Every sub-command is one module of :mod:`shellbuckle.commands` (``register(subparsers)`` adds
it and sets its ``func``), found at start-up; the options several commands share are declared
once in :mod:`shellbuckle.commands._options`. :func:`main` runs the command and keeps the exit
codes: 0 on success, 2 on bad input (a ``ValueError`` or ``FileNotFoundError``: its message on
stderr), 130 when interrupted by Ctrl-C (SIGINT) and 143 by SIGTERM (which takes the same path:
a run is stored as interrupted, resumable), whatever the code was doing (an interrupt inside a
compiled kernel or a linear solver surfaces as another exception, whose chain holds it), 1 on
any other failure during the work (a run that left the physical domain among them).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import os
import pkgutil
import signal
import sys
import threading

from .util import interrupt_of


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




class Terminated(KeyboardInterrupt):
    """SIGTERM, raised by the handler :func:`main` installs: it takes the interrupt path of
    Ctrl-C (the run is stored as interrupted, resumable), with exit code 128 + the signal."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _terminate(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def _sigterm_interrupts():
    """SIGTERM raises :class:`Terminated` inside the block (main thread only: elsewhere the
    handler cannot be installed and SIGTERM keeps its disposition)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class _Plain(logging.Formatter):
    """A log record as one line of the command line: ``shellbuckle CMD: warning: ...`` (an
    error the command goes on after, such as one failed figure of a study, is a warning too:
    ``failed:`` is the last line of a command that failed); a traceback is left to ``-v``."""

    def __init__(self, command):
        super().__init__()
        self.head = f"shellbuckle {command}" if command else "shellbuckle"

    def format(self, record) -> str:
        kind = "warning" if record.levelno >= logging.WARNING else record.levelname.lower()
        more = " (-v shows the traceback)" if record.exc_info else ""
        return f"{self.head}: {kind}: {' '.join(record.getMessage().split())}{more}"


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # plain: `shellbuckle CMD: warning: ...` (docs/errors.md); -v: every record with its logger
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s")
                         if args.verbose else _Plain(getattr(args, "command", None)))
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        handlers=[handler])
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with _sigterm_interrupts():
            code = int(args.func(args) or 0)
        sys.stdout.flush()  # a reader gone shows here while the output was still buffered
        return code
    except (ValueError, FileNotFoundError) as exc:
        interrupt = interrupt_of(exc)
        if interrupt is not None:
            return _interrupted(args.command, interrupt)
        print(f"shellbuckle {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        return _interrupted(args.command, exc)
    except BrokenPipeError as exc:
        if _reader_gone():  # `shellbuckle analyze DIR | head`: stop quietly, as Unix tools do
            return 128 + signal.SIGPIPE
        print(f"shellbuckle {args.command}: failed: {type(exc).__name__}: {exc}",
              file=sys.stderr)
        return 1
    except Exception as exc:  # a failure during the work, not bad input
        interrupt = interrupt_of(exc)
        if interrupt is not None:
            return _interrupted(args.command, interrupt)
        logging.getLogger("shellbuckle").debug("failure", exc_info=True)
        from .commands._checks import WorkFailed

        why = exc if isinstance(exc, WorkFailed) else f"{type(exc).__name__}: {exc}"
        print(f"shellbuckle {args.command}: failed: {why}", file=sys.stderr)
        return 1


def _reader_gone() -> bool:
    """Whether standard output is a pipe whose reader has closed it (the pipe reports an error
    or hang-up to ``poll``); if so, it is pointed at the null device, so that Python's own
    flush at exit does not report the broken pipe again. False where it cannot be told."""
    import select

    try:
        fd = sys.stdout.fileno()
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        gone = any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no file descriptor, no poll (Windows)
        return False
    if gone:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
    return gone


def _interrupted(command: str, interrupt: KeyboardInterrupt) -> int:
    """Report an interrupt; its exit code: 130 for Ctrl-C (SIGINT), 128 + the signal for
    :class:`Terminated` (143 for SIGTERM)."""
    how = f" ({interrupt})" if str(interrupt) else ""
    print(f"shellbuckle {command}: interrupted{how}", file=sys.stderr)
    return 128 + getattr(interrupt, "signum", signal.SIGINT)


if __name__ == "__main__":
    sys.exit(main())
