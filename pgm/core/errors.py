"""Error types, and the one place that says which failures are the user's to fix.

Every problem with user input (a file, a box, a parameter) is raised as
:class:`InputError`, a subclass of :class:`ValueError` whose message is one line
naming the problem. :func:`user_message` maps every *expected* failure — bad input,
a file system that refuses a path, a run too large for the memory — to that one line;
the CLI prints it as ``pgm: error: <message>`` and exits with code 2. Anything else is
a bug in the toolkit (``pgm: internal error``, exit 1).
"""

from __future__ import annotations

import contextlib
import errno
import signal

__all__ = ["InputError", "DegenerateWeightsError", "RuleContractError", "Interrupted",
           "user_message", "one_line", "uninterrupted", "interrupt"]


class InputError(ValueError):
    """Bad user input: a missing or corrupt file, a malformed box, a bad parameter."""


class DegenerateWeightsError(ValueError):
    """Every particle weight is zero (all log-weights are -inf or NaN)."""


class RuleContractError(RuntimeError):
    """An inference rule broke its contract (e.g. a likelihood rule moved particles).

    A programming error in a rule, not bad input: it names the rule and the factor.
    """


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal (SIGINT or SIGTERM).

    A :class:`KeyboardInterrupt`, so every ``finally`` and ``except KeyboardInterrupt``
    that cleans up after Ctrl-C does the same for SIGTERM (what a cluster scheduler
    sends): rows written so far are kept and the annotated video is finalised.
    """

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @property
    def name(self) -> str:
        """``"SIGINT"`` or ``"SIGTERM"``."""
        return signal.Signals(self.signum).name


#: blocks a signal must not cut (depth), and the signal that arrived inside one
_HELD: dict[str, int | None] = {"depth": 0, "pending": None}


def interrupt(signum: int) -> None:
    """What a SIGINT/SIGTERM handler calls: raise :class:`Interrupted` now, or, inside an
    :func:`uninterrupted` block, when the block ends."""
    if _HELD["depth"]:
        _HELD["pending"] = int(signum)
        return
    raise Interrupted(signum)


@contextlib.contextmanager
def uninterrupted():
    """A block that a signal does not cut in the middle (e.g. muxing a video packet: cut
    there, the file loses its index and plays no frame); a signal that arrives inside it
    is raised when it ends."""
    _HELD["depth"] += 1
    try:
        yield
    finally:
        _HELD["depth"] -= 1
        if not _HELD["depth"] and _HELD["pending"] is not None:
            signum, _HELD["pending"] = _HELD["pending"], None
            raise Interrupted(signum)


def one_line(text: object) -> str:
    """``text`` with every run of white space (newlines included) made one space."""
    return " ".join(str(text).split())


_OS_VERBS = {errno.ENOSPC: "no space left on the device for",
             errno.EDQUOT: "disk quota exceeded writing",
             errno.EROFS: "read-only file system:"}


def user_message(exc: BaseException) -> str | None:
    """The one-line message of an expected failure, or None for a bug.

    Expected: :class:`ValueError` (the API's contract for bad input, :class:`InputError`
    included), :class:`OSError` (a path the file system refuses: missing, not a folder,
    a folder where a file should be, no permission, disk full), :class:`MemoryError`
    (a run larger than the memory; the runners refuse most of these before they start,
    see :func:`pgm.app.memory.estimate_memory`). Everything else — ``TypeError``,
    ``KeyError``, an OpenCV error, ... — is a bug and gets None.
    """
    if isinstance(exc, ValueError):
        return one_line(exc) or type(exc).__name__
    if isinstance(exc, OSError):
        path = exc.filename if exc.filename is not None else ""
        reason = exc.strerror or one_line(exc) or type(exc).__name__
        verb = _OS_VERBS.get(exc.errno or 0)
        if verb is not None and path:
            return f"{verb} {path}"
        return f"{reason}: {path}" if path else one_line(reason)
    if isinstance(exc, MemoryError):
        return ("out of memory (" + (one_line(exc) or "MemoryError") + "); use fewer "
                "--particles or smaller frames")
    return None
