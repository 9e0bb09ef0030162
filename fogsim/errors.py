"""Errors that reach the user as one clear line naming the file and the problem, and the one
error → exit-code policy of the command line (:func:`exit_code`, :func:`describe`, applied by
:func:`run_command`)."""

import sys


class FogsimError(Exception):
    """Base class. The CLI prints ``str(exc)`` and exits non-zero, without a traceback."""


class InputError(FogsimError):
    """A user input (file, dataset, argument value) is missing, unreadable or malformed.

    ``source`` names the offending file (or dataset record) so messages always say which.
    """

    def __init__(self, source, problem: str):
        self.source = str(source)
        self.problem = problem
        super().__init__(f"{self.source}: {problem}")


class MissingDependency(FogsimError):
    """An optional extra (bpy, torch, Ultralytics, pyarrow …) is needed but not installed."""


# ----------------------------------------------------------------------------- exit codes
#: The one error → exit-code policy of every front door (``fogsim …``, ``render_batch.py``).
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def exit_code(exc: BaseException) -> int:
    """Exit code for an error that ended a command.

    Usage and setup errors — a bad flag or value (``ValueError``), a bad input
    (:class:`InputError`), a missing extra, an unwritable path (``OSError``) — exit 2; any
    other fogsim error is a failure of the work itself and exits 1; Ctrl-C exits 130.
    """
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    if isinstance(exc, (InputError, MissingDependency, ValueError, OSError)):
        return EXIT_USAGE
    return EXIT_FAILED


def describe(exc: BaseException) -> str:
    """The one line printed for an error: what and where, never a traceback."""
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    if isinstance(exc, OSError) and not isinstance(exc, FogsimError):
        where = exc.filename or ""
        return f"{where}: {exc.strerror or exc}" if where else str(exc)
    return str(exc)


def unexpected(exc: BaseException) -> str:
    """The one line for an error a unit of work (a frame, a sample) ended with that is no input problem:
    its type and text; memory running out says so in words (a MemoryError often has no text)."""
    if isinstance(exc, MemoryError):
        return f"out of memory (MemoryError{': ' + str(exc) if str(exc) else ''}): the work needed more memory " \
               "than the machine (or its limit) gives"
    return f"{type(exc).__name__}: {exc}"


def run_command(command, args, prog: str = "fogsim") -> int:
    """Run ``command(args)`` under the one error → exit-code policy: a fogsim error, a bad value
    (``ValueError``), an OS error or Ctrl-C ends it with ``<prog>: error: <one line>`` on stderr
    and :func:`exit_code`; any other exception is a bug and propagates (its traceback is the
    useful report)."""
    try:
        return command(args)
    except (FogsimError, ValueError, OSError, KeyboardInterrupt) as exc:
        print(f"{prog}: error: {describe(exc)}", file=sys.stderr)
        return exit_code(exc)
