"""Output folders that never lie: one run's results, written honestly.

A run writes ``tracks.txt`` and ``annotated.mp4`` as it goes, and ``metrics.json``,
``model.json`` and the final ``run.json`` only when it has finished. The rules:

* :func:`prepare_run_folder` creates the folder (or checks it is one) and **removes
  the previous run's results** from it — the names of :data:`RUN_OUTPUTS` (the five a
  run writes, and ``view.html``, the page ``pgm view`` made of the previous run), and
  nothing else — so a new ``tracks.txt`` never sits next to an older run's
  ``metrics.json`` or page. A symbolic link with one of those names is removed, never
  followed.
* :func:`write_run_status` writes ``run.json`` atomically (a temporary file renamed over
  it): ``"complete": false`` from the start of a run, with ``"stopped"`` saying why when
  it was interrupted or failed, and ``"complete": true`` once every result is written.
  A folder whose ``run.json`` is missing or says ``false`` holds a partial run.
* :func:`write_json` writes any JSON result atomically.

Every refusal of the file system (a file where the folder should be, no permission,
a read-only parent) is an :class:`~pgm.core.errors.InputError` naming the path.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError
from pgm.core.version import __version__

__all__ = ["RUN_OUTPUTS", "prepare_run_folder", "prepare_output_file", "write_json", "write_text",
           "write_run_status"]

def _umask() -> int:
    old = os.umask(0o022)
    os.umask(old)
    return old


_FILE_MODE = 0o666 & ~_umask()  # what open() would give a new file

#: the files one run writes into its output folder, and the viewer page made of it
#: (removed before the next run there: a page left from a --record run would show an
#: earlier run next to the new results)
RUN_OUTPUTS = ("tracks.txt", "annotated.mp4", "metrics.json", "run.json", "model.json",
               "view.html")


def _why(exc: OSError) -> str:
    return exc.strerror or " ".join(str(exc).split()) or type(exc).__name__


def prepare_run_folder(path: str | Path) -> Path:
    """Create the output folder ``path`` (parents too) and remove an earlier run's
    results from it (:data:`RUN_OUTPUTS`; other files are left alone). Returns it."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InputError(f"output folder {out} exists and is not a folder")
    blocker = next((a for a in out.parents if a.exists() and not a.is_dir()), None)
    if blocker is not None:
        raise InputError(f"cannot create output folder {out}: {blocker} is a file, not a "
                         f"folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output folder {out}: {_why(exc)}") from None
    for name in RUN_OUTPUTS:
        p = out / name
        if p.is_symlink() or p.exists():
            if p.is_dir() and not p.is_symlink():
                raise InputError(f"output folder {out} holds a folder named {name}; "
                                 f"remove it or choose another --out")
            try:
                p.unlink()
            except OSError as exc:
                raise InputError(f"cannot remove the earlier {p}: {_why(exc)}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"cannot write into output folder {out}: permission denied")
    return out


def prepare_output_file(path: str | Path, what: str = "--out") -> Path:
    """Check that ``path`` can become a file (not a folder; parent creatable)."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{what} {p} is a folder; give a file name")
    blocker = next((a for a in p.parents if a.exists() and not a.is_dir()), None)
    if blocker is not None:
        raise InputError(f"cannot write {what} {p}: {blocker} is a file, not a folder")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {p.parent} for {what}: {_why(exc)}") from None
    if p.is_symlink():
        try:
            p.unlink()  # replaced, never followed
        except OSError as exc:
            raise InputError(f"cannot replace {p}: {_why(exc)}") from None
    return p


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically: a temporary file in the same folder,
    renamed over ``path``, so a reader sees the old file or the whole new one; a symbolic
    link at ``path`` is replaced, not followed."""
    p = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)
            os.chmod(tmp, _FILE_MODE)
            os.replace(tmp, p)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError as exc:
        raise InputError(f"cannot write {p}: {_why(exc)}") from None
    return p


def write_json(path: str | Path, data: Any) -> Path:
    """Write ``data`` as JSON to ``path`` atomically (:func:`write_text`)."""
    return write_text(path, json.dumps(data, indent=1))


def provenance(rng: Any, command: Sequence[str] | None = None) -> dict[str, Any]:
    """What ``run.json`` records to reproduce a run: ``"seed"`` (the integer seed; None
    where a generator was given), ``"command"`` (the argument list, ``pgm`` first, where
    the run came from the command line; None from the API), ``"pgm_version"`` and
    ``"commit"`` (the toolkit's git commit where it runs from a checkout, with ``+dirty``
    when its tracked files differ from it; None for an installed copy)."""
    seed = int(rng) if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) else None
    return {"seed": seed, "command": None if command is None else [str(a) for a in command],
            "pgm_version": __version__, "commit": toolkit_commit()}


@functools.lru_cache(maxsize=1)
def toolkit_commit() -> str | None:
    """The git commit of the checkout the toolkit runs from (``+dirty`` appended when its
    tracked files differ), or None (an installed copy, no git, or git too slow)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"], capture_output=True, text=True,
                               timeout=5, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{head}+dirty" if dirty else head or None


def write_run_status(out: Path, info: dict[str, Any], *, complete: bool,
                     stopped: str | None = None) -> Path:
    """Write ``out/run.json``: ``info`` with ``"complete"`` (and ``"stopped"``: why a
    run that did not finish ended)."""
    data = {"complete": bool(complete), **info}
    if stopped is not None:
        data["stopped"] = stopped
    return write_json(Path(out) / "run.json", data)
