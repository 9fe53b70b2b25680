"""Running ``pgm`` in the test's own process: one helper for every CLI test."""

from __future__ import annotations

from pgm.app.cli import main


def run_cli(capsys, *argv):
    """``(exit code, stdout, stderr)`` of ``pgm ARGV`` run in this process; ``argv`` may
    also be one list. An argparse error's ``SystemExit`` is its exit code."""
    if len(argv) == 1 and isinstance(argv[0], (list, tuple)):
        argv = tuple(argv[0])
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err
