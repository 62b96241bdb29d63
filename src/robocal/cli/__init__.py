"""The ``robocal`` command: parse, call the API, write files atomically, print, return an exit code.

Exit codes: 0 success, 1 an optional extra is missing, 2 bad input or usage (one line on stderr,
nothing written). This package is the only place that prints or configures logging
(docs/cli.md). Each command lives in its own module with ``register(subparsers)`` and ``run(args)``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import warnings

from .._base.errors import RobocalError, RobocalWarning
from .._version import __version__
from . import (
    calibrate,
    common,
    compensate,
    export,
    history,
    identifiability,
    import_bag,
    import_dh,
    import_urdf,
    limit,
    plan,
    plan_sockets,
    record,
    report,
    simulate,
    verify,
)
from .common import CommandParser, Formatter, MissingExtra, Parser

COMMANDS = (plan, plan_sockets, simulate, calibrate, compensate, export, identifiability, report, limit, import_urdf,
            import_dh, import_bag, record, history, verify)


EXAMPLE = """example:
  robocal calibrate examples/th8/model.yaml examples/th8/measurements.csv --out runs/first --known markers

Each command has its own help with examples: robocal COMMAND --help (docs/cli.md)."""


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="robocal", description="Robot calibration: geometric and compliance "
                                     "parameters, identifiability, the limit of absolute accuracy.",
                    epilog=EXAMPLE, formatter_class=Formatter)
    parser.add_argument("--version", action="version", version=f"robocal {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=CommandParser)
    for command in COMMANDS:
        command.register(sub)
    for command_parser in sub.choices.values():  # `robocal COMMAND -v` as well as `robocal -v COMMAND`
        command_parser.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                                    help="log progress")
    return parser


class _CommandHandler(logging.StreamHandler):
    """The handler the command line adds to the ``robocal`` logger (one at a time): progress said
    after ``robocal:``, a warning after ``robocal: warning:`` as every other warning is."""

    def format(self, record: logging.LogRecord) -> str:
        return ("robocal: warning: " if record.levelno >= logging.WARNING else "robocal: ") + record.getMessage()


def _configure_logging(verbose: bool) -> None:
    """The library logs progress through ``logging`` (logger ``robocal``); only here is it shown."""
    logger = logging.getLogger("robocal")
    for h in [h for h in logger.handlers if isinstance(h, _CommandHandler)]:
        logger.removeHandler(h)          # a handler of an earlier call holds an earlier stderr
    handler = _CommandHandler(sys.stderr)
    logger.addHandler(handler)
    logger.setLevel(logging.INFO if verbose else logging.WARNING)
    logger.propagate = False


def _quiet_stdout() -> None:
    """Point stdout at the null device so that Python's exit-time flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):   # no real file behind stdout: nothing to flush
        pass


class _Reader:
    """stdout that, once its reader has left (``robocal ... | head``), drops the rest quietly: the
    command still does all its work and ends with its own exit code (3 for a failed calibration)."""

    def __init__(self, stream):
        self._stream, self._left = stream, False

    def _guarded(self, call, *args):
        if not self._left:
            try:
                return call(*args)
            except BrokenPipeError:
                self._left = True
                _quiet_stdout()
        return None

    def write(self, text: str) -> int:
        self._guarded(self._stream.write, text)
        return len(text)

    def flush(self) -> None:
        self._guarded(self._stream.flush)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def main(argv=None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, --version, usage errors: argparse has printed
        return e.code if isinstance(e.code, int) else 2
    if getattr(args, "func", None) is None:
        parser.print_help(sys.stderr)
        return 2
    _configure_logging(args.verbose)
    shown: list[str] = []

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, RobocalWarning):
            shown.append(str(message))
            print(f"robocal: warning: {one_line(message)}", file=sys.stderr)
        else:  # a library's warning: one line too, saying whose
            print(f"robocal: warning: {category.__name__}: {one_line(message)}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("always", RobocalWarning)
        # numpy's overflow and invalid-value warnings speak of its internals: the results they
        # touch are checked finite and a command says what is wrong in its own words
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.showwarning = show
        args.shown_warnings = shown
        logging.getLogger("robocal").info("%s: started", args.command)
        stdout, sys.stdout = sys.stdout, _Reader(sys.stdout)
        try:
            with _sigterm_unwinds():
                return _run(args)
        finally:
            sys.stdout = stdout


def _terminate(signum, frame):
    raise KeyboardInterrupt  # unwinds like Ctrl-C: the writers remove their temporary files


@contextlib.contextmanager
def _sigterm_unwinds():
    """SIGTERM raises KeyboardInterrupt for the command's run, the host's handler restored after.

    Here and not in the library: a program that imports robocal owns its signal handlers."""
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave signals alone
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _run(args) -> int:
    """The command, with every error the user can act on as one line on stderr."""
    def fail(message: str, code: int = 2) -> int:
        print(f"robocal {args.command}: {message}", file=sys.stderr)
        return code

    token = common.INPUTS.set(common.input_files(args))
    try:
        return args.func(args)
    except RobocalError as e:
        return fail(f"error: {one_line(e)}")
    except MissingExtra as e:
        return fail(str(e), 1)
    except BrokenPipeError:  # `robocal ... | head`: the reader left; say nothing more
        _quiet_stdout()
        return 0
    except OSError as e:  # the output folder cannot be made or written: the user's to fix
        name = str(e.filename or "")
        where = f"{name if len(name) <= 200 else name[:100] + '...'}: " if name else ""
        return fail(f"error: {where}{e.strerror or e}")
    except MemoryError as e:  # numpy says how much it tried to allocate
        return fail(f"error: out of memory{f' ({one_line(e)})' if str(e) else ''}; use fewer poses or samples")
    except KeyboardInterrupt:
        return fail("interrupted; nothing was written", 130)
    finally:
        common.INPUTS.reset(token)


def one_line(e: BaseException) -> str:
    """An error's message on one line, cut to a length a terminal shows."""
    text = " ".join(str(e).split())
    return text if len(text) <= 500 else text[:500] + "..."


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
