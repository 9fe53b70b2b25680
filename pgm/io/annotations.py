"""Ground-truth and result files: OTB, MILTrack and MOTChallenge.

Every box returned here is top-left ``(x, y, w, h)`` in the toolkit's 0-based pixel
coordinates (pixel ``(row i, column j)`` covers ``[j, j+1) x [i, i+1)``); use
:func:`pgm.core.boxes.xywh_to_cxcywh` for centre form. Files keep their own conventions and
are converted at the boundary:

* **OTB** ``groundtruth_rect.txt`` and **MOTChallenge** ``gt.txt``/``det.txt``/results:
  1-based (MATLAB) top-left ``x, y`` — 1 is subtracted on reading, added on writing.
* **MILTrack** ``*_gt.txt`` (FaceOcc1): 0-based (C++/OpenCV origin) — read as is.

Frame numbers are 1-based everywhere.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pgm.core.errors import InputError
from pgm.io.track_files import MotWriter, format_numbers, write_otb_groundtruth  # re-exported

__all__ = [
    "SingleTrack",
    "MotTable",
    "MotWriter",
    "TrackRows",
    "MOT16_PEDESTRIAN",
    "MOT16_DISTRACTOR_CLASSES",
    "write_otb_groundtruth",
    "format_numbers",
    "load_single_gt",
    "load_mot",
    "load_tracks",
    "detect_gt_format",
]

_SPLIT = re.compile(r"[,\s]+")
_FORMATS = ("otb", "miltrack", "mot")

#: largest box coordinate or size (px) read from an annotation or detection file: no
#: image is a million pixels wide, and a row beyond it (``1e300``) is refused naming
#: the file and the line, not met later as a non-finite model parameter
MAX_COORDINATE = 1e6
#: largest frame number (and identity) read from a MOTChallenge file
MAX_FRAME = 10**9


# --------------------------------------------------------------------------- parsing


def _read_lines(path: Path) -> list[str]:
    """Lines of a text file, trailing blank lines dropped."""
    if not path.exists():
        raise InputError(f"no such file: {path}")
    if not path.is_file():
        raise InputError(f"not a file: {path}")
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise InputError(f"cannot read {path}: {' '.join(str(exc).split())}") from None
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def _parse_table(path: Path, lines: list[str], *, min_cols: int, max_cols: int | None,
                 sep: re.Pattern[str] = _SPLIT, what: str = "values"
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parse numeric rows; returns ``(values (n, width), line_numbers (n,), lengths (n,))``
    (``lengths``: the numbers on each line, to tell a written ``nan`` from a padded one).

    Blank lines are an error (they would shift the line-to-frame pairing); rows shorter
    than the widest row are padded with NaN. ``line_numbers`` are 1-based.
    """
    rows = [sep.split(s.strip()) for s in lines]
    lengths = np.fromiter((0 if r == [""] else len(r) for r in rows), dtype=int,
                          count=len(rows))
    if rows:
        upper = max_cols if max_cols is not None else int(lengths.max())
        bad = np.flatnonzero((lengths < min_cols) | (lengths > upper))
        if bad.size:
            i = int(bad[0])
            want = (f"{min_cols}" if max_cols == min_cols
                    else f"{min_cols} to {max_cols}" if max_cols is not None
                    else f"at least {min_cols}")
            raise InputError(f"{path}:{i + 1}: expected {want} {what}, got {lengths[i]}"
                             f" ({lines[i].strip()[:60]!r})")
    width = int(lengths.max()) if rows else min_cols
    table = np.full((len(rows), width), np.nan)
    flat = [v for r in rows for v in r]
    try:
        values = np.array(flat, dtype=float)
    except ValueError:
        for i, r in enumerate(rows):
            try:
                [float(v) for v in r]
            except ValueError:
                raise InputError(f"{path}:{i + 1}: non-numeric value in"
                                 f" {lines[i].strip()[:60]!r}") from None
        raise  # pragma: no cover - unreachable: some row must have failed
    if np.all(lengths == width):
        table[:] = values.reshape(len(rows), width)
    else:
        row_idx = np.repeat(np.arange(len(rows)), lengths)
        col_idx = np.arange(values.size) - np.repeat(np.cumsum(lengths) - lengths, lengths)
        table[row_idx, col_idx] = values
    return table, np.arange(1, len(rows) + 1), lengths


# --------------------------------------------------------------------------- single object


@dataclass(frozen=True, eq=False)
class SingleTrack:
    """One object's boxes on the frames where it is annotated, and the frames where it is
    annotated as absent.

    Attributes
    ----------
    frames : ndarray of int, shape (K,)
        1-based frame numbers that carry a box, increasing.
    boxes : ndarray of float, shape (K, 4)
        Top-left ``(x, y, w, h)``, 0-based internal pixel coordinates, ``w, h > 0``.
    absent : ndarray of int, shape (A,)
        1-based frame numbers where the annotation says the object is not visible (fully
        occluded or out of view: UAV123's ``NaN`` rows), increasing; none by default.
        A frame in neither ``frames`` nor ``absent`` is unannotated (not scored).
    """

    frames: np.ndarray
    boxes: np.ndarray
    absent: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        frames = np.asarray(self.frames, dtype=np.int64).reshape(-1)
        boxes = np.asarray(self.boxes, dtype=float).reshape(-1, 4)
        absent = np.asarray(self.absent, dtype=np.int64).reshape(-1)
        if frames.shape[0] != boxes.shape[0]:
            raise ValueError(f"{frames.shape[0]} frames but {boxes.shape[0]} boxes")
        both = np.intersect1d(frames, absent)
        if both.size:
            raise ValueError(f"frame {int(both[0])} is annotated both with a box and as absent")
        object.__setattr__(self, "frames", frames)
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "absent", absent)

    def __len__(self) -> int:
        return int(self.frames.shape[0])

    def until(self, last_frame: int) -> SingleTrack:
        """The annotations of frames ``<= last_frame`` (to score a run that stopped early)."""
        keep = self.frames <= int(last_frame)
        return SingleTrack(self.frames[keep], self.boxes[keep],
                           self.absent[self.absent <= int(last_frame)])

    def since(self, first_frame: int) -> SingleTrack:
        """The annotations of frames ``>= first_frame`` (to score a run's later part)."""
        keep = self.frames >= int(first_frame)
        return SingleTrack(self.frames[keep], self.boxes[keep],
                           self.absent[self.absent >= int(first_frame)])


def detect_gt_format(path: str | Path) -> str:
    """Guess ``'otb'``, ``'miltrack'`` or ``'mot'`` for a ground-truth file.

    ``groundtruth_rect*.txt`` is OTB; ``gt.txt`` is MOT; any other ``*_gt.txt`` is
    MILTrack; otherwise a first line with 6 or more columns is MOT and anything else
    is taken as OTB (1-based).
    """
    p = Path(path)
    name = p.name.lower()
    if name.startswith("groundtruth_rect"):
        return "otb"
    if name == "gt.txt":
        return "mot"
    if name.endswith("_gt.txt"):
        return "miltrack"
    for line in _read_lines(p):
        if line.strip():
            return "mot" if len(_SPLIT.split(line.strip())) >= 6 else "otb"
    return "otb"


def load_single_gt(path: str | Path, fmt: str = "auto", *, obj_id: int | None = None
                   ) -> SingleTrack:
    """Load a single object's ground truth.

    Parameters
    ----------
    path : str or Path
        The annotation file.
    fmt : {'auto', 'otb', 'miltrack', 'mot'}
        * ``'otb'`` — ``groundtruth_rect.txt``: line *i* (1-based) is frame *i*, four
          numbers ``x, y, w, h`` separated by commas, tabs or spaces; 1-based ``x, y``.
          A line with NaN marks a frame where the object is **absent** (fully occluded
          or out of view: UAV123's convention; ``absent``); a line with a non-positive
          width or height marks a frame without annotation, skipped.
        * ``'miltrack'`` — ``*_gt.txt`` of the MILTrack release (FaceOcc1): line *k*
          (0-based) is frame *k + 1*; ``0,0,0,0`` means "not annotated" and is skipped;
          **0-based** ``x, y`` (C++/OpenCV origin), read unchanged.
        * ``'mot'`` — a MOTChallenge ``gt.txt``; the identity ``obj_id`` (default: the
          first identity in frame order) is taken; rows with flag 0 (ignore) are skipped.
        * ``'auto'`` — :func:`detect_gt_format`.
    obj_id : int, optional
        Identity to take from a MOT file.

    Returns
    -------
    SingleTrack
        The annotated frames and their 0-based top-left boxes, and the frames annotated
        as absent.

    Raises
    ------
    InputError
        Missing file, unknown format, a line that does not parse (named with its line
        number), no annotated frame at all, or ``obj_id`` not in the file.
    """
    p = Path(path)
    if fmt == "auto":
        fmt = detect_gt_format(p)
    if fmt not in _FORMATS:
        raise InputError(f"unknown ground-truth format {fmt!r} for {p}"
                         f" (expected one of auto, {', '.join(_FORMATS)})")
    if fmt == "mot":
        return _single_from_mot(p, obj_id)
    lines = _read_lines(p)
    table, _, _ = _parse_table(p, lines, min_cols=4, max_cols=4, what="numbers (x, y, w, h)")
    boxes = table[:, :4]
    frames = np.arange(1, len(lines) + 1, dtype=np.int64)
    valid = np.all(np.isfinite(boxes), axis=1) & (boxes[:, 2] > 0) & (boxes[:, 3] > 0)
    huge = valid & np.any(np.abs(boxes) > MAX_COORDINATE, axis=1)
    if np.any(huge):
        i = int(np.flatnonzero(huge)[0])
        raise InputError(f"{p}:{i + 1}: box coordinates beyond ±{MAX_COORDINATE:g} px "
                         f"({lines[i].strip()[:60]!r})")
    if fmt == "otb":
        boxes = boxes.copy()
        boxes[:, :2] -= 1.0
    if not np.any(valid):
        raise InputError(f"no annotated box in {p}")
    absent = (frames[np.any(np.isnan(table[:, :4]), axis=1)] if fmt == "otb"
              else np.zeros(0, dtype=np.int64))
    return SingleTrack(frames=frames[valid], boxes=boxes[valid], absent=absent)


def _single_from_mot(p: Path, obj_id: int | None) -> SingleTrack:
    table = load_mot(p, kind="gt")
    if len(table) == 0:
        raise InputError(f"no annotated box in {p}")
    if obj_id is None:
        obj_id = int(table.ids[0])  # rows are sorted by frame, file order within a frame
    sel = table.ids == obj_id
    if not np.any(sel):
        raise InputError(f"identity {obj_id} not found in {p}")
    frames = table.frames[sel]
    if np.any(np.diff(frames) == 0):
        dup = int(frames[np.flatnonzero(np.diff(frames) == 0)[0]])
        raise InputError(f"identity {obj_id} has two boxes in frame {dup} of {p}")
    keep = ~table.ignore[sel]
    if not np.any(keep):
        raise InputError(f"identity {obj_id} has only ignored (flag 0) rows in {p}")
    return SingleTrack(frames=frames[keep], boxes=table.boxes[sel][keep])


# --------------------------------------------------------------------------- MOTChallenge


@dataclass(frozen=True, eq=False)
class MotTable:
    """Rows of a MOTChallenge-style file, sorted by frame (file order kept within a frame).

    Attributes
    ----------
    frames : ndarray of int, shape (K,)
        1-based frame numbers.
    ids : ndarray of int, shape (K,)
        Identities (``-1`` for detections).
    boxes : ndarray of float, shape (K, 4)
        Top-left ``(x, y, w, h)``, 0-based internal coordinates.
    conf : ndarray of float, shape (K,)
        Column 7: the evaluation flag for ground truth, the score for detections and
        results (1.0 when the file has only six columns).
    ignore : ndarray of bool, shape (K,)
        Ground-truth rows that are *ignore regions*: a prediction matched to one is
        neither a true nor a false positive. MOT15: rows with flag 0; MOT16/17: the
        distractor classes 2, 7, 8 and 12 (:data:`MOT16_DISTRACTOR_CLASSES`). All False
        for detections and results.
    scored : ndarray of bool, shape (K,)
        Ground-truth rows scored as targets (default: the rows that are not ignore
        regions). MOT16/17: class 1 with ``consider`` = 1; rows of other classes are
        neither scored nor ignore regions (a prediction on an occluder is a false
        positive).
    classes : ndarray of int, shape (K,)
        MOT16/17 class of each row (``-1`` where the file has none).
    visibility : ndarray of float, shape (K,)
        MOT16/17 visible fraction of each row (NaN where the file has none).
    fmt : str
        ``"mot15"`` (or a detection / result file) or ``"mot16"`` (the 2016/17 ground
        truth with ``consider, class, visibility`` columns).
    """

    frames: np.ndarray
    ids: np.ndarray
    boxes: np.ndarray
    conf: np.ndarray
    ignore: np.ndarray | None = None
    scored: np.ndarray | None = None
    classes: np.ndarray | None = None
    visibility: np.ndarray | None = None
    fmt: str = "mot15"
    _index: dict[int, tuple[int, int]] = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        # copies: the columns are made read-only, which must not touch the caller's arrays
        frames = np.array(self.frames, dtype=np.int64).reshape(-1)
        k = frames.shape[0]
        ids = np.array(self.ids, dtype=np.int64).reshape(-1)
        boxes = np.array(self.boxes, dtype=float).reshape(-1, 4)
        conf = np.array(self.conf, dtype=float).reshape(-1)
        ignore = (np.zeros(k, dtype=bool) if self.ignore is None
                  else np.array(self.ignore, dtype=bool).reshape(-1))
        scored = (~ignore if self.scored is None
                  else np.array(self.scored, dtype=bool).reshape(-1))
        classes = (np.full(k, -1, dtype=np.int64) if self.classes is None
                   else np.array(self.classes, dtype=np.int64).reshape(-1))
        visibility = (np.full(k, np.nan) if self.visibility is None
                      else np.array(self.visibility, dtype=float).reshape(-1))
        if not all(a.shape[0] == k for a in (ids, boxes, conf, ignore, scored, classes,
                                             visibility)):
            raise ValueError("MotTable columns have different lengths")
        if np.any(scored & ignore):
            raise ValueError("MotTable: a row cannot be both scored and an ignore region")
        if self.fmt not in ("mot15", "mot16"):
            raise ValueError(f"MotTable: fmt must be 'mot15' or 'mot16', got {self.fmt!r}")
        cols = {"frames": frames, "ids": ids, "boxes": boxes, "conf": conf, "ignore": ignore,
                "scored": scored, "classes": classes, "visibility": visibility}
        order = np.argsort(frames, kind="stable")
        if np.any(order != np.arange(k)):
            cols = {name: value[order] for name, value in cols.items()}
        for name, value in cols.items():
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        frames = cols["frames"]
        uniq, starts, counts = np.unique(frames, return_index=True, return_counts=True)
        index = {int(f): (int(s), int(s + c)) for f, s, c in zip(uniq, starts, counts,
                                                                  strict=True)}
        object.__setattr__(self, "_index", index)

    def __len__(self) -> int:
        return int(self.frames.shape[0])

    def frame_numbers(self) -> np.ndarray:
        """Sorted distinct frame numbers that have at least one row."""
        return np.fromiter(self._index.keys(), dtype=np.int64, count=len(self._index))

    def rows(self, frame: int) -> slice:
        """Slice of the rows of ``frame`` (empty when it has none); O(1)."""
        start, stop = self._index.get(int(frame), (0, 0))
        return slice(start, stop)

    def subset(self, keep: np.ndarray) -> MotTable:
        """The rows where ``keep`` (a boolean mask) is true, every column kept."""
        keep = np.asarray(keep, dtype=bool)
        return MotTable(frames=self.frames[keep], ids=self.ids[keep], boxes=self.boxes[keep],
                        conf=self.conf[keep], ignore=self.ignore[keep],
                        scored=self.scored[keep], classes=self.classes[keep],
                        visibility=self.visibility[keep], fmt=self.fmt)

    def until(self, frame: int) -> MotTable:
        """The rows of frames ``<= frame``."""
        return self.subset(self.frames <= int(frame))

    def at(self, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(ids (n,), boxes (n, 4), conf (n,))`` of one frame (read-only views)."""
        s = self.rows(frame)
        return self.ids[s], self.boxes[s], self.conf[s]


class TrackRows:
    """A run's track rows — frame, identity, box ``(x, y, w, h)``, score — gathered frame
    by frame in numpy arrays that double when full, handed over as a
    :class:`MotTable` at the end (its evaluation, the returned result).

    56 bytes a row (at most twice that while the arrays wait to be filled), where Python
    lists of the numbers took about 320: an hour of 20 tracks at 30 frames/s holds 121 MB
    instead of about 680.
    """

    def __init__(self, capacity: int = 1024):
        capacity = max(1, int(capacity))
        self.n = 0
        self.frames = np.zeros(capacity, dtype=np.int64)
        self.ids = np.zeros(capacity, dtype=np.int64)
        self.boxes = np.zeros((capacity, 4))
        self.scores = np.zeros(capacity)

    def __len__(self) -> int:
        return self.n

    @property
    def nbytes(self) -> int:
        """Bytes the arrays hold (filled or not)."""
        return sum(a.nbytes for a in (self.frames, self.ids, self.boxes, self.scores))

    def extend(self, frames, ids, boxes, scores) -> None:
        """Append rows: ``frames``, ``ids``, ``scores`` ``(k,)``, ``boxes`` ``(k, 4)``."""
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        k = len(boxes)
        if self.n + k > len(self.frames):
            size = max(2 * len(self.frames), self.n + k)
            for name in ("frames", "ids", "boxes", "scores"):
                old = getattr(self, name)
                new = np.zeros((size,) + old.shape[1:], dtype=old.dtype)
                new[:self.n] = old[:self.n]
                setattr(self, name, new)
        end = self.n + k
        self.frames[self.n:end] = frames
        self.ids[self.n:end] = ids
        self.boxes[self.n:end] = boxes
        self.scores[self.n:end] = scores
        self.n = end

    def table(self) -> MotTable:
        """The rows as a :class:`MotTable` (copies)."""
        n = self.n
        return MotTable(self.frames[:n].copy(), self.ids[:n].copy(), self.boxes[:n].copy(),
                        self.scores[:n].copy())


def load_caviar(path: str | Path) -> MotTable:
    """Read a CAVIAR ground-truth file (the CVML XML of the CAVIAR project, the VB-PHD
    paper's data set) as a :class:`MotTable`.

    The file is ``<dataset><frame number="F"><objectlist><object id="I"><box xc=".."
    yc=".." w=".." h=".."/>…``: one ``frame`` element per frame (``number`` 0-based;
    stored here as ``F + 1``, the MOTChallenge convention), one ``object`` per person
    with its box centre ``(xc, yc)`` and size ``(w, h)`` in pixels. Other elements
    (orientation, appearance, hypotheses, groups) are not read. Every box is scored (no
    ignore regions). The XML is parsed with the standard library (entities are not
    expanded into the file system; no code runs).

    Raises
    ------
    InputError
        Not XML, no ``frame`` element, a frame or object without a number / id, a box
        with missing, non-finite or non-positive values, an identity twice in a frame.
    """
    import xml.etree.ElementTree as ET

    p = Path(path)
    if not p.is_file():
        raise InputError(f"no such file: {p}")
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise InputError(f"{p} is not a CAVIAR XML file: {exc}") from None
    frames_el = root.findall(".//frame")
    if not frames_el:
        raise InputError(f"{p}: no <frame> element (not CAVIAR ground truth)")
    rows: list[tuple[int, int, float, float, float, float]] = []
    for fr in frames_el:
        try:
            number = int(fr.attrib["number"])
        except (KeyError, ValueError):
            raise InputError(f"{p}: a <frame> without an integer number "
                             f"({fr.attrib.get('number')!r})") from None
        seen: set[int] = set()
        for obj in fr.iter("object"):
            try:
                oid = int(obj.attrib["id"])
            except (KeyError, ValueError):
                raise InputError(f"{p}: frame {number}: an <object> without an integer id") \
                    from None
            if oid in seen:
                raise InputError(f"{p}: frame {number}: object {oid} appears twice")
            seen.add(oid)
            box = obj.find("box")
            try:
                xc, yc, w, h = (float(box.attrib[k]) for k in ("xc", "yc", "w", "h"))
            except (AttributeError, KeyError, ValueError):
                raise InputError(f"{p}: frame {number}, object {oid}: <box> needs numbers "
                                 f"xc, yc, w, h") from None
            if not all(np.isfinite((xc, yc, w, h))) or w <= 0 or h <= 0:
                raise InputError(f"{p}: frame {number}, object {oid}: box "
                                 f"({xc}, {yc}, {w}, {h}) is not finite and positive")
            rows.append((number + 1, oid, xc - w / 2, yc - h / 2, w, h))
    r = np.array(rows, dtype=float).reshape(-1, 6)
    return MotTable(r[:, 0].astype(np.int64), r[:, 1].astype(np.int64), r[:, 2:6],
                    np.ones(len(r)))


def load_mot(path: str | Path, *, kind: str = "gt", min_score: float | None = None,
             absent_rows: bool = False) -> MotTable:
    """Read a MOTChallenge ``gt.txt``, ``det.txt`` or result file (or, for ground truth,
    a CAVIAR ``.xml`` file: :func:`load_caviar`).

    Rows are ``frame, id, x, y, w, h, conf[, ...]`` with 1-based top-left ``x, y``
    (converted to 0-based). Ground truth comes in two layouts, told apart from the file:

    * **MOT15** (10 columns; world coordinates after the flag): column 7 is the
      evaluation flag; flag-0 rows are ignore regions;
    * **MOT16/17** (exactly 9 columns ``..., consider, class, visibility`` with
      ``consider`` in {0, 1}, integer classes 1–12 and visibility in [0, 1]): the
      benchmark's protocol — class 1 with ``consider`` = 1 are the targets, classes 2,
      7, 8 and 12 are ignore regions, every other row is neither
      (:attr:`MotTable.scored`, :attr:`MotTable.ignore`).

    Parameters
    ----------
    path : str or Path
        The file.
    kind : {'gt', 'det'}
        ``'gt'``: column 7 is the evaluation flag; rows with flag 0 are kept and marked
        in :attr:`MotTable.ignore`. ``'det'``: column 7 is a score.
    min_score : float, optional
        For ``kind='det'``: keep only rows with score ``>= min_score``.

    Raises
    ------
    InputError
        Missing file, fewer than 6 columns, a non-numeric value, a non-integer frame or
        id, a frame number below 1, a non-positive or non-finite box, a written
        non-finite score (``nan``, ``inf``; a missing column 7 reads as 1) (named with
        the file and line number); ``min_score`` with ``kind='gt'``.
    """
    if kind == "gt" and Path(path).suffix.lower() == ".xml":
        return load_caviar(path)
    p = Path(path)
    if kind not in ("gt", "det"):
        raise InputError(f"kind must be 'gt' or 'det' (got {kind!r}) for {p}")
    if min_score is not None and kind != "det":
        raise InputError(f"min_score applies to detections (kind='det') only, for {p}")
    lines = _read_lines(p)
    table, lineno, lengths = _parse_table(p, lines, min_cols=6, max_cols=None,
                                 what="comma-separated columns")
    if table.shape[1] < 7:
        table = np.concatenate([table, np.full((table.shape[0], 7 - table.shape[1]),
                                               np.nan)], axis=1)
    if absent_rows:  # a tracker's row of NaN: the target reported absent in that frame
        present = ~np.all(np.isnan(table[:, 2:6]), axis=1)
        if not present.all():
            table, lineno, lengths = table[present], lineno[present], lengths[present]
            lines = [line for line, keep in zip(lines, present, strict=True) if keep]
    frames_f, ids_f, boxes, conf = table[:, 0], table[:, 1], table[:, 2:6], table[:, 6]
    checks = (
        (~np.isfinite(frames_f) | (frames_f != np.round(frames_f)) | (frames_f < 1)
         | (frames_f > MAX_FRAME), f"frame must be an integer from 1 to {MAX_FRAME}"),
        (~np.isfinite(ids_f) | (ids_f != np.round(ids_f)), "id must be an integer"),
        (~np.all(np.isfinite(boxes), axis=1), "box is not finite"),
        (np.any(np.abs(boxes) > MAX_COORDINATE, axis=1),
         f"box coordinates beyond ±{MAX_COORDINATE:g} px"),
        (~((boxes[:, 2] > 0) & (boxes[:, 3] > 0)), "box width and height must be > 0"),
        ((lengths >= 7) & ~np.isfinite(conf),
         "score/flag (column 7) is not finite" if kind == "det" else
         "flag (column 7) is not finite"),
    )
    for bad, message in checks:
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{p}:{lineno[i]}: {message} ({lines[i].strip()[:60]!r})")
    ids = _exact_ids(p, lines, lineno, ids_f)
    conf = np.where(np.isnan(conf), 1.0, conf)
    boxes = boxes.copy()
    boxes[:, :2] -= 1.0
    keep = np.ones(len(lines), dtype=bool)
    if min_score is not None:
        keep = conf >= float(min_score)
    extra: dict = {}
    if kind == "gt" and _is_mot16_gt(table):
        classes = table[:, 7].astype(np.int64)
        ignore = np.isin(classes, MOT16_DISTRACTOR_CLASSES)
        scored = (classes == MOT16_PEDESTRIAN) & (conf == 1)
        extra = {"scored": scored[keep], "classes": classes[keep],
                 "visibility": table[keep, 8], "fmt": "mot16"}
    else:
        ignore = (conf == 0) if kind == "gt" else np.zeros(len(lines), dtype=bool)
    return MotTable(frames=frames_f[keep].astype(np.int64), ids=ids[keep],
                    boxes=boxes[keep], conf=conf[keep], ignore=ignore[keep], **extra)


def _exact_ids(path: Path, lines: list[str], lineno: np.ndarray, ids_f: np.ndarray
               ) -> np.ndarray:
    """The id column as ``int64``, exactly: any 64-bit integer is an id. Ids of magnitude
    2^53 and above (where a float no longer holds every integer) are read again from
    their text; one that is not a 64-bit integer is an :class:`InputError` naming its
    line."""
    ids = np.zeros(len(ids_f), dtype=np.int64)
    small = np.abs(ids_f) < 2.0 ** 53
    ids[small] = ids_f[small].astype(np.int64)
    for i in np.flatnonzero(~small):
        text = _SPLIT.split(lines[i].strip())[1]
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not -2 ** 63 <= value < 2 ** 63:
            raise InputError(f"{path}:{lineno[i]}: id must be a 64-bit integer "
                             f"({lines[i].strip()[:60]!r})")
        ids[i] = value
    return ids


#: MOT16/17 ground-truth class of the evaluated targets (pedestrians)
MOT16_PEDESTRIAN = 1
#: MOT16/17 classes whose boxes are ignore regions (person on vehicle, static person,
#: distractor, reflection): predictions matched to them are removed before scoring
MOT16_DISTRACTOR_CLASSES = (2, 7, 8, 12)


def _is_mot16_gt(table: np.ndarray) -> bool:
    """Whether a parsed ``gt.txt`` has the MOT16/17 ``consider, class, visibility`` columns."""
    if table.shape[1] != 9 or table.shape[0] == 0:
        return False
    consider, cls, vis = table[:, 6], table[:, 7], table[:, 8]
    return bool(np.all(np.isin(consider, (0.0, 1.0))) and np.all(cls == np.round(cls))
                and np.all((cls >= 1) & (cls <= 12)) and np.all((vis >= 0) & (vis <= 1)))


def load_tracks(path: str | Path) -> MotTable:
    """Read a tracker's MOTChallenge result file (as written by :class:`MotWriter`).

    Same as ``load_mot(path, kind='det')``, and an identity may appear at most once per
    frame. A row whose box is ``NaN,NaN,NaN,NaN`` says the target is absent in that frame
    and is left out, as a missing row is (the long-term convention).

    Raises
    ------
    InputError
        As :func:`load_mot`, or an identity with two boxes in one frame.
    """
    p = Path(path)
    table = load_mot(p, kind="det", absent_rows=True)
    if len(table):
        pairs = np.stack([table.frames, table.ids], axis=1)
        uniq, counts = np.unique(pairs, axis=0, return_counts=True)
        if np.any(counts > 1):
            f, i = uniq[np.flatnonzero(counts > 1)[0]]
            raise InputError(f"track {int(i)} has two boxes in frame {int(f)} of {p}")
    return table
