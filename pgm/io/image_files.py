"""The image files of a folder as frames: which files are images, their natural order
(``a2`` before ``a10``), and a warning where their numbering has a gap (used by
:mod:`pgm.io.video`)."""

from __future__ import annotations

import logging
import re
from pathlib import Path

from pgm.core.errors import InputError

__all__ = ["IMAGE_EXTENSIONS", "natural_key"]

IMAGE_EXTENSIONS: frozenset[str] = frozenset({".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff"})
"""File-name suffixes (lower case) recognised as images in a folder."""

_DIGITS = re.compile(r"(\d+)")
_log = logging.getLogger(__name__)


def natural_key(name: str) -> tuple:
    """Sort key that orders embedded integers numerically (``a2`` < ``a10``)."""
    parts = _DIGITS.split(name)
    return tuple((0, int(p), p) if p.isdigit() else (1, 0, p.lower()) for p in parts)


def _list_images(folder: Path, ext: str | None = None) -> list[Path]:
    """Image files directly in ``folder`` (one extension, or any image one), natural order."""
    if ext is not None:
        want = {ext.lower()}
    else:
        want = IMAGE_EXTENSIONS
    files = [p for p in folder.iterdir() if p.suffix.lower() in want and p.is_file()]
    if not files:
        kinds = " ".join(sorted(want))
        raise InputError(f"no image files ({kinds}) in folder {folder}")
    files.sort(key=lambda p: natural_key(p.name))
    return files


_NUMBERED = re.compile(r"(.*?)(\d+)$")


def _warn_numbering_gap(folder: Path, files: list[Path]) -> None:
    """A warning where the image files are numbered (one prefix, a number) with a gap: the
    frames are numbered by the files' order, so a ground truth or detections kept by frame
    number pair with other images after it (a file missing from a copy)."""
    found = [_NUMBERED.fullmatch(p.stem) for p in files]
    if len(files) < 2 or not all(found) or len({m.group(1) for m in found}) != 1:
        return
    numbers = [int(m.group(2)) for m in found]
    gap = next((k for k in range(1, len(numbers)) if numbers[k] != numbers[k - 1] + 1), None)
    if gap is not None:
        _log.warning("%s: the images are numbered with a gap (%s, then %s): frames are "
                     "numbered in the files' order, so annotations by frame number shift "
                     "from frame %d on", folder, files[gap - 1].name, files[gap].name, gap + 1)
