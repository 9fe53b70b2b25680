"""Per-frame detections: the measurements a multi-target filter consumes, streamed.

A :class:`DetectionSource` is called once per frame, in frame order, with
``(frame_number, image)`` as yielded by :meth:`pgm.io.video.FrameSource.frames` and
returns a :class:`Detections`: top-left ``(x, y, w, h)`` boxes in the toolkit's 0-based
pixel coordinates and one score per box. Two sources are provided:

:class:`PublicDetections`
    The MOTChallenge public detections of a sequence (``det/det.txt``), looked up per
    frame in O(1); the image is ignored. Scores are in the file's own units.
:class:`MOG2Detector`
    Background subtraction (OpenCV MOG2) for a static camera: foreground mask, shadows
    removed, morphological clean-up, one box per connected component of plausible size
    and shape. Stateful: it must see the frames in order.
:class:`CallableDetector`
    A user's own detector (YOLO, RT-DETR, ...): a function from a frame to boxes and
    scores (``pgm track --detector my_module:detect`` or ``--detector my_file.py:detect``).

:func:`make_detector` builds either from a short spec string (``"public"``,
``"public:40"``, ``"mog2"``).

Score ranges of the shared sequences' ``det/det.txt``
-----------------------------------------------------
The MOT15 public detections (ACF) carry a raw detector confidence, **not** a probability
in ``[0, 1]``:

=====================  ======  ==================  ===========================
sequence               rows    min .. max          5 / 50 / 95 % quantiles
=====================  ======  ==================  ===========================
PETS09-S2L1-video      5578    -0.48 .. 138.9      10.1 / 67.0 / 104.4
PETS09-S2L1 (240 fr.)  1730    -0.48 .. 138.9      10.0 / 62.4 / 101.5
TUD-Campus             322     0.09 .. 117.9       7.1 / 37.2 / 78.7
TUD-Stadtmitte         1129    -0.15 .. 122.4      9.7 / 55.1 / 102.3
=====================  ======  ==================  ===========================

so a ``min_score`` is given in those units (e.g. ``"public:30"``); see
``benchmarks/detections.py`` for precision/recall on PETS09-S2L1 at several thresholds.

Known limitation of blob detection
----------------------------------
People walking close together form one connected foreground blob and are reported as
one (wide) box; a person split by an occluder (PETS's lamp post) or by a background-
coloured garment may give two, and a person who stands still fades into the
background. ``benchmarks/detections.py`` measures the merging on PETS09-S2L1: with the
:class:`MOG2Detector` defaults, over frames 1-200, 14 % of the detections are one box
over two or more people and 24 % of the people are inside such a box (the public
detections, all rows: 5 % and 12 % by the same measure). About half of MOG2's
misses at IoU >= 0.3 are people in a merged blob; most of the rest are people partly
hidden (lamp post, sign) or partly absorbed while standing.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from pgm.core.boxes import iou_xywh
from pgm.core.errors import InputError
from pgm.io.annotations import MotTable, load_mot

from .detection_base import Detections, DetectionSource
from .hog import HOGPeopleDetector

_log = logging.getLogger(__name__)

__all__ = [
    "Detections",
    "pair_boxes",
    "DetectionSource",
    "PublicDetections",
    "MOG2Detector",
    "CallableDetector",
    "make_detector",
    "DETECTOR_SPECS",
    "MatchCounts",
    "match_detections",
]

DETECTOR_SPECS: tuple[str, ...] = ("public", "public:<min_score>", "mog2", "hog",
                                   "<module or file.py>:<function>")
"""The spec strings :func:`make_detector` accepts."""


def _check_score(min_score: Any, where: str) -> float | None:
    if min_score is None:
        return None
    try:
        value = float(min_score)
    except (TypeError, ValueError):
        raise InputError(f"min_score must be a number (got {min_score!r}) for {where}") from None
    if not math.isfinite(value):
        raise InputError(f"min_score must be finite (got {min_score!r}) for {where}")
    return value


class PublicDetections(DetectionSource):
    """MOTChallenge public detections (``det/det.txt``), looked up per frame.

    Parameters
    ----------
    path_or_table : str, Path or MotTable
        A ``det.txt`` file (read with ``load_mot(kind='det')``) or an already loaded
        table.
    min_score : float, optional
        Keep only rows with score ``>= min_score``, **in the file's own units** (MOT15
        scores run from about 0 to 140, not 0 to 1; see the module docstring).

    Raises
    ------
    InputError
        A missing or malformed file (the message names the file and line), or a
        ``min_score`` that is not a finite number.

    Notes
    -----
    The image is ignored; frames without a row give an empty :class:`Detections`.
    Each call is O(1) (a slice of the frame-sorted table). Frames may be requested in
    any order.
    """

    def __init__(self, path_or_table: str | Path | MotTable, min_score: float | None = None
                 ) -> None:
        if isinstance(path_or_table, MotTable):
            self.path: Path | None = None
            where = "the detection table"
            min_score = _check_score(min_score, where)
            table = path_or_table
            if min_score is not None:
                keep = table.conf >= min_score
                table = MotTable(frames=table.frames[keep], ids=table.ids[keep],
                                 boxes=table.boxes[keep], conf=table.conf[keep])
        else:
            self.path = Path(path_or_table)
            min_score = _check_score(min_score, str(self.path))
            table = load_mot(self.path, kind="det", min_score=min_score)
            if not len(table):  # a run would track nothing and say nothing
                _log.warning("%s holds no detection%s: every frame is tracked without one",
                             self.path, "" if min_score is None
                             else f" scored at least {min_score:g}")
        self.table: MotTable = table
        self.min_score: float | None = min_score
        self.name = "public" if min_score is None else f"public:{min_score:g}"

    def __call__(self, frame_number: int, image: np.ndarray | None = None) -> Detections:
        _, boxes, conf = self.table.at(int(frame_number))
        return Detections(boxes, conf)

    @property
    def score_range(self) -> tuple[float, float] | None:
        """``(min, max)`` score of the kept rows, or None when there is none."""
        if len(self.table) == 0:
            return None
        return float(self.table.conf.min()), float(self.table.conf.max())


def _kernel(size: Any, what: str) -> np.ndarray | None:
    """A rectangular structuring element from ``k`` or ``(kw, kh)``; 0 means none."""
    if size is None:
        return None
    if isinstance(size, (int, np.integer)):
        kw = kh = int(size)
    else:
        try:
            kw, kh = (int(v) for v in size)
        except (TypeError, ValueError):
            raise InputError(f"{what} must be an int or a (width, height) pair"
                             f" (got {size!r})") from None
    if kw < 0 or kh < 0:
        raise InputError(f"{what} must be >= 0 (got {size!r})")
    if kw <= 1 and kh <= 1:
        return None
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (max(kw, 1), max(kh, 1)))


class MOG2Detector(DetectionSource):
    """Moving-blob detections from OpenCV's MOG2 background subtractor.

    Per frame: ``createBackgroundSubtractorMOG2(history, var_threshold,
    detect_shadows).apply(image, learningRate=learning_rate)``; the mask is thresholded
    at 255 (foreground; shadow pixels are 127 and dropped); an optional Gaussian blur of
    the image before subtraction (``blur``) damps compression noise; an opening
    (``open_size``) removes speckle, a closing (``close_size``, taller than wide) joins a
    person's head, torso and legs; ``cv2.connectedComponentsWithStats`` (8-connected)
    gives one box per blob. A blob is kept when its pixel area is ``>= min_area``, its
    box height ``>= min_height`` and its height/width ratio within
    ``[min_aspect, max_aspect]``.

    Parameters
    ----------
    history, var_threshold, detect_shadows
        MOG2's own parameters (OpenCV defaults: 500, 16, True).
    min_area : float
        Minimum foreground pixels in a blob (PETS09-S2L1 people: 750-2200, 5-95 %).
    min_height : float
        Minimum box height in pixels.
    min_aspect, max_aspect : float
        Accepted range of box height / width (PETS09-S2L1 people: 1.9-3.7, 5-95 %;
        two people side by side in one blob fall below 1.5).
    open_size, close_size : int or (width, height)
        Elliptic structuring elements of the opening and the closing; 0 or 1 skips.
    blur : int
        Odd Gaussian kernel size applied to the image first; 0 skips.
    background_ratio : float
        MOG2's ``backgroundRatio`` (OpenCV default 0.9): the share of the pixel's
        mixture weight that counts as background. A still person is absorbed into the
        background once their colour holds more than ``1 - background_ratio`` of the
        weight, which with the automatic rate ``1/n`` takes only about 10 % of the frames
        seen so far at 0.9; 0.7 keeps people who pause visible three times longer (and
        lets the ghost of someone present in the first frame last as long).
    learning_rate : float
        Passed to ``apply``; -1 lets MOG2 choose ``1 / min(frames seen, history)``.
    warmup : int
        The first ``warmup`` frames only train the model and return no detection.

    Notes
    -----
    *Score*: the blob's **fill ratio**, foreground pixels / box area, in ``(0, 1]``. On
    PETS09-S2L1 a detected person fills 0.37-0.67 (5-95 %, median 0.52) of the box, and
    blobs that match nobody span about the same range: it is a shape descriptor, not a
    confidence, and filters should not rely on it to reject clutter.

    *State*: the background model is updated on every call, so call the detector once
    per frame in increasing frame order (gaps are allowed: the model just sees fewer
    frames). A frame number that does not increase, or an image of another size, raises
    :class:`InputError`; :meth:`reset` starts afresh. Given the same frames in the same
    order the output is deterministic.

    *Defaults* were compared on the first 200 frames of PETS09-S2L1 (``vtest.avi``,
    768x576, people about 30x80 px) against the flag-1 ground truth (pooled over
    frames; ``benchmarks/detections.py`` prints the table). With these defaults:
    precision 0.953 / recall 0.756 at IoU >= 0.3 (0.938 / 0.744 with foot points within
    20 px), 4.8 detections per frame, about 13 ms per frame on one CPU thread; over the
    full 795 frames 0.954 / 0.837. OpenCV's background ratio 0.9 with a 7x15 closing
    gave 0.957 / 0.659 (still people absorbed); ``var_threshold=25`` 0.976 / 0.757.
    About 14 % of the detections are one box over a group of two or more people, and
    24 % of the people are inside such a box: group merging is the largest single
    cause of misses (about half of them; see the module docstring).
    """

    def __init__(self, history: int = 500, var_threshold: float = 16.0,
                 detect_shadows: bool = True, *, min_area: float = 400.0,
                 min_height: float = 40.0, min_aspect: float = 1.0, max_aspect: float = 5.0,
                 open_size: Any = 3, close_size: Any = (3, 9), blur: int = 0,
                 background_ratio: float = 0.7, learning_rate: float = -1.0,
                 warmup: int = 0) -> None:
        def number(value: Any, what: str, lo: float, *, strict: bool = False) -> float:
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise InputError(f"MOG2Detector: {what} must be a number (got {value!r})"
                                 ) from None
            if not math.isfinite(v) or v < lo or (strict and v == lo):
                op = ">" if strict else ">="
                raise InputError(f"MOG2Detector: {what} must be finite and {op} {lo:g}"
                                 f" (got {value!r})")
            return v

        self.history = int(number(history, "history", 1))
        self.var_threshold = number(var_threshold, "var_threshold", 0, strict=True)
        self.detect_shadows = bool(detect_shadows)
        self.min_area = number(min_area, "min_area", 0)
        self.min_height = number(min_height, "min_height", 0)
        self.min_aspect = number(min_aspect, "min_aspect", 0)
        self.max_aspect = number(max_aspect, "max_aspect", 0, strict=True)
        if self.max_aspect < self.min_aspect:
            raise InputError(f"MOG2Detector: max_aspect ({max_aspect!r}) is below min_aspect"
                             f" ({min_aspect!r})")
        self.open_size, self.close_size = open_size, close_size
        self._open = _kernel(open_size, "MOG2Detector: open_size")
        self._close = _kernel(close_size, "MOG2Detector: close_size")
        self.blur = int(number(blur, "blur", 0))
        if self.blur > 1 and self.blur % 2 == 0:
            raise InputError(f"MOG2Detector: blur must be 0 or an odd size (got {blur!r})")
        lr = number(learning_rate, "learning_rate", -math.inf)
        if not (lr < 0 or lr <= 1):
            raise InputError(f"MOG2Detector: learning_rate must be negative (automatic) or"
                             f" in [0, 1] (got {learning_rate!r})")
        self.learning_rate = lr
        self.warmup = int(number(warmup, "warmup", 0))
        self.background_ratio = number(background_ratio, "background_ratio", 0, strict=True)
        if self.background_ratio > 1:
            raise InputError(f"MOG2Detector: background_ratio must be in (0, 1] (got"
                             f" {background_ratio!r})")
        self.name = "mog2"
        self.reset()

    def reset(self) -> None:
        """Drop the background model; the next call starts a new one."""
        self._mog = cv2.createBackgroundSubtractorMOG2(self.history, self.var_threshold,
                                                       self.detect_shadows)
        self._mog.setBackgroundRatio(self.background_ratio)
        self._last_frame: int | None = None
        self._shape: tuple[int, ...] | None = None
        self._seen = 0
        self.mask: np.ndarray | None = None
        """The cleaned foreground mask (uint8 0/255) of the last frame, for display."""

    def __call__(self, frame_number: int, image: np.ndarray | None) -> Detections:
        frame_number = int(frame_number)
        if image is None:
            raise InputError("MOG2Detector needs the image of every frame (got None)")
        image = np.asarray(image)
        if image.ndim not in (2, 3) or image.dtype != np.uint8:
            raise InputError(f"MOG2Detector: expected a uint8 image (H, W[, 3]), got"
                             f" {image.dtype} {image.shape}")
        if self._last_frame is not None and frame_number <= self._last_frame:
            raise InputError(f"MOG2Detector is stateful: frame {frame_number} after frame"
                             f" {self._last_frame}; call frames in increasing order or"
                             " reset() first")
        if self._shape is not None and image.shape != self._shape:
            raise InputError(f"MOG2Detector: frame {frame_number} has shape {image.shape},"
                             f" earlier frames {self._shape}; reset() for a new video")
        self._last_frame, self._shape = frame_number, image.shape
        self._seen += 1
        src = cv2.GaussianBlur(image, (self.blur, self.blur), 0) if self.blur > 1 else image
        raw = self._mog.apply(src, learningRate=self.learning_rate)
        if self._seen <= self.warmup:
            self.mask = None
            return Detections.empty()
        mask = cv2.threshold(raw, 254, 255, cv2.THRESH_BINARY)[1]  # 255 fg, 127 shadow
        if self._open is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        if self._close is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)
        self.mask = mask
        return self._blobs(mask)

    def _blobs(self, mask: np.ndarray) -> Detections:
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        st = stats[1:n].astype(float)  # label 0 is the background
        x, y, w, h, area = st[:, 0], st[:, 1], st[:, 2], st[:, 3], st[:, 4]
        aspect = h / w
        keep = ((area >= self.min_area) & (h >= self.min_height)
                & (aspect >= self.min_aspect) & (aspect <= self.max_aspect))
        boxes = np.stack([x, y, w, h], axis=1)[keep]
        scores = (area / (w * h))[keep]
        return Detections(boxes, scores)


# --------------------------------------------------------------------------- factory


class CallableDetector(DetectionSource):
    """A user's own detector: a function from a frame to boxes and scores.

    ``fn(image)`` gets each frame (``H x W x 3`` BGR ``uint8``, as OpenCV reads it) in
    frame order and returns either :class:`Detections`, or ``(boxes, scores)`` with
    ``boxes`` top-left ``(x, y, w, h)`` in pixels ``(M, 4)`` and ``scores`` ``(M,)``, or
    one ``(M, 5)`` array of ``x, y, w, h, score`` rows (``M`` may be 0). Scores may be on
    any scale: the multi-target default reads them by their quantile among the video's
    scores; a core that reads the detector's own numbers (``--scores detector``) takes
    them as probabilities in ``[0, 1]`` unless ``fn.score_range = (low, high)`` says
    otherwise, and ``fn.score_range = None`` that they carry no confidence at all (as
    background subtraction's fill fractions: every detection is then taken as
    confident). A box with a non-positive or non-finite size, a non-finite coordinate or
    score, or a return value of another shape is an :class:`InputError` naming the
    detector and the frame (the user's code: one line, never a traceback).

    >>> import numpy as np
    >>> det = CallableDetector(lambda img: (np.array([[10, 20, 30, 60]]), np.array([0.9])),
    ...                        name="mine")
    >>> det(1, np.zeros((100, 100, 3), np.uint8)).boxes.tolist()
    [[10.0, 20.0, 30.0, 60.0]]
    """

    def __init__(self, fn, name: str = "callable"):
        if not callable(fn):
            raise InputError(f"detector {name!r} is not callable (got {type(fn).__name__})")
        self.fn = fn
        self.name = str(name)
        rng = getattr(fn, "score_range", (0.0, 1.0))
        #: the scale of the scores (what the models' score maps are chosen from; None: no
        #: confidence)
        self.score_range: np.ndarray | None = None
        if rng is None:
            return
        try:
            lo, hi = (float(v) for v in rng)
        except (TypeError, ValueError):
            raise InputError(f"detector {self.name!r}: score_range must be (low, high), got "
                             f"{rng!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise InputError(f"detector {self.name!r}: score_range must be finite with "
                             f"low <= high, got {rng!r}")
        self.score_range = np.array([lo, hi])

    def __call__(self, frame_number: int, image: np.ndarray | None) -> Detections:
        where = f"detector {self.name!r}, frame {frame_number}"
        if image is None:
            raise InputError(f"{where}: it needs the frame's image")
        try:
            out = self.fn(image)
        except InputError:
            raise
        except Exception as exc:  # noqa: BLE001 - the user's code: any failure, one line
            raise InputError(f"{where}: {type(exc).__name__}: {' '.join(str(exc).split())}"
                             ) from None
        if isinstance(out, Detections):
            boxes, scores = out.boxes, out.scores
        else:
            try:
                if isinstance(out, tuple) and len(out) == 2:
                    boxes = np.asarray(out[0], dtype=float).reshape(-1, 4)
                    scores = np.asarray(out[1], dtype=float).reshape(-1)
                else:
                    rows = np.asarray(out, dtype=float)
                    if rows.size == 0:
                        rows = rows.reshape(0, 5)
                    if rows.ndim != 2 or rows.shape[1] != 5:
                        raise ValueError(f"an array of shape {rows.shape}")
                    boxes, scores = rows[:, :4], rows[:, 4]
            except (TypeError, ValueError) as exc:
                raise InputError(f"{where}: expected Detections, (boxes (M, 4), scores (M,)) "
                                 f"or an (M, 5) array, got {' '.join(str(exc).split())}"
                                 ) from None
        if boxes.shape[0] != scores.shape[0]:
            raise InputError(f"{where}: {boxes.shape[0]} boxes but {scores.shape[0]} scores")
        bad = (~np.all(np.isfinite(boxes), axis=1) | ~np.isfinite(scores)
               | ~((boxes[:, 2] > 0) & (boxes[:, 3] > 0)))
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: detection {i} is {boxes[i].tolist()} with score "
                             f"{scores[i]!r} (a box needs finite x, y, w > 0, h > 0 and a "
                             f"finite score)")
        return Detections(boxes, scores)


#: the built-in detectors' names (a ``name:argument`` spec of one of them is not a function)
BUILTIN_DETECTORS = ("public", "mog2", "hog")


def names_a_function(spec: str | None) -> bool:
    """Whether a detector spec names a user's function (``module:function`` or
    ``file.py:function``) rather than a built-in detector (``public:MIN`` is one)."""
    if not spec or ":" not in spec:
        return False
    module, _, fn = spec.rpartition(":")
    return (bool(module.strip()) and fn.strip().isidentifier()
            and module.strip().lower() not in BUILTIN_DETECTORS)


def make_detector(spec: str, source: Any = None) -> DetectionSource:
    """Build a :class:`DetectionSource` from a spec string.

    Parameters
    ----------
    spec : str
        ``'public'`` — the source's ``det/det.txt`` (:class:`PublicDetections`);
        ``'public:<min_score>'`` — the same, keeping scores ``>= min_score`` (file
        units, e.g. ``'public:30'`` for MOT15); ``'mog2'`` — :class:`MOG2Detector` with
        its defaults.
    source : FrameSource, optional
        The sequence; needed for ``'public'`` (its ``det_path``).

    Raises
    ------
    InputError
        An unknown spec (the message lists the choices), a bad ``min_score``, a source
        without public detections, or a missing/malformed ``det.txt``.
    """
    text = str(spec).strip()
    kind, sep, arg = text.partition(":")
    kind = kind.strip().lower()
    choices = ", ".join(repr(s) for s in DETECTOR_SPECS)
    if kind == "public":
        min_score = None
        if sep:
            try:
                min_score = float(arg)
            except ValueError:
                min_score = math.nan
            if not math.isfinite(min_score):
                raise InputError(f"bad detector spec {spec!r}: min_score {arg.strip()!r} is"
                                 f" not a finite number (choices: {choices})")
        det_path = getattr(source, "det_path", None)
        if det_path is None:
            name = getattr(source, "name", None) or getattr(source, "path", None) or source
            raise InputError(f"detector {text!r}: source {name} has no public detections"
                             " (det/det.txt); use 'mog2'")
        return PublicDetections(det_path, min_score=min_score)
    if kind == "mog2" and not sep:
        return MOG2Detector()
    if kind == "hog" and not sep:
        return HOGPeopleDetector()
    if names_a_function(text):
        raise InputError(f"detector {spec!r} names a user's function (module:function): "
                         f"the application imports it (pgm track --detector {spec}); from "
                         f"Python pass CallableDetector(function)")
    raise InputError(f"unknown detector {spec!r} (choices: {choices})")


# --------------------------------------------------------------------------- evaluation


@dataclass(frozen=True)
class MatchCounts:
    """Detection-vs-ground-truth counts of one or more frames.

    ``tp`` matched detections, ``fp`` unmatched detections (those passing the match
    test against an ignored ground-truth box excluded), ``fn`` unmatched ground-truth
    boxes; ``merged`` detections that each cover (hold at least half the box of) two or
    more ground-truth people and overlap (IoU) the union box of those people more than
    any one of them — one box for a group — and ``people_in_merged`` the people so
    covered; ``n_det`` and
    ``n_gt`` all detections and all (not ignored) ground-truth boxes.
    """

    tp: int = 0
    fp: int = 0
    fn: int = 0
    merged: int = 0
    people_in_merged: int = 0
    n_det: int = 0
    n_gt: int = 0

    def __add__(self, other: MatchCounts) -> MatchCounts:
        return MatchCounts(*(getattr(self, f) + getattr(other, f)
                             for f in ("tp", "fp", "fn", "merged", "people_in_merged",
                                       "n_det", "n_gt")))

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else math.nan

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else math.nan


def _foot(b: np.ndarray) -> np.ndarray:
    return np.stack([b[:, 0] + b[:, 2] / 2.0, b[:, 1] + b[:, 3]], axis=1)


def pair_boxes(ok: np.ndarray, score: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one pairs ``(rows, cols)`` of a (rows × cols) table of valid pairs ``ok``
    that maximise the number of pairs, then the total ``score`` (in [-1, 1]; IoU or a
    scaled negative distance) among them, by
    :func:`scipy.optimize.linear_sum_assignment`. Only valid pairs are returned.

    Maximising the total score alone (and dropping the invalid pairs afterwards) can
    give up a valid pair for a better total: one box that overlaps two others well
    may be spent on the one that a third box could also have taken.
    """
    ok = np.asarray(ok, dtype=bool)
    if ok.size == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    # a valid pair is worth 1 + eps * score, an invalid one 0: with eps = 1 / (2 m + 1)
    # (m: the most pairs there can be) k pairs are worth more than any k - 1, whatever
    # their scores, so the count comes first and the score only breaks ties
    eps = 1.0 / (2 * min(ok.shape) + 1)
    gain = np.where(ok, 1.0 + eps * np.clip(np.asarray(score, dtype=float), -1.0, 1.0), 0.0)
    r, c = linear_sum_assignment(gain, maximize=True)
    good = ok[r, c]
    return r[good], c[good]


def match_detections(dets: Detections, gt_boxes: np.ndarray, ignore_boxes: np.ndarray | None
                     = None, *, criterion: str = "iou", iou_min: float = 0.3,
                     foot_px: float = 20.0) -> MatchCounts:
    """One-to-one matching of one frame's detections to its ground truth.

    ``criterion='iou'`` pairs a detection and a ground-truth box when their IoU is
    ``>= iou_min``; ``'foot'`` when their foot points are within ``foot_px`` pixels.
    The assignment maximises the number of pairs (then the total IoU / minimises the
    total distance) with :func:`scipy.optimize.linear_sum_assignment`. Unmatched
    detections that pass the same test against an ignored (MOT flag 0) box are not
    counted as false positives.
    """
    gt = np.asarray(gt_boxes, dtype=float).reshape(-1, 4)
    ign = (np.zeros((0, 4)) if ignore_boxes is None
           else np.asarray(ignore_boxes, dtype=float).reshape(-1, 4))
    d = dets.boxes
    if criterion == "iou":
        def affinity(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            s = iou_xywh(a[:, None, :], b[None, :, :])
            return s >= iou_min, s
    elif criterion == "foot":
        def affinity(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            dist = np.linalg.norm(_foot(a)[:, None, :] - _foot(b)[None, :, :], axis=-1)
            return dist <= foot_px, -dist / (foot_px + 1.0)
    else:
        raise InputError(f"criterion must be 'iou' or 'foot' (got {criterion!r})")
    tp = 0
    matched = np.zeros(len(d), dtype=bool)
    if len(d) and len(gt):
        r, _ = pair_boxes(*affinity(d, gt))
        tp = len(r)
        matched[r] = True
    unmatched = ~matched
    if np.any(unmatched) and len(ign):
        ok_ign, _ = affinity(d[unmatched], ign)
        unmatched[np.flatnonzero(unmatched)[ok_ign.any(axis=1)]] = False
    merged = people_in_merged = 0
    if len(d) and len(gt):
        # a detection "covers" a person when it holds at least half of the person's box
        a, b = d[:, None, :], gt[None, :, :]
        iw = np.clip(np.minimum(a[..., 0] + a[..., 2], b[..., 0] + b[..., 2])
                     - np.maximum(a[..., 0], b[..., 0]), 0, None)
        ih = np.clip(np.minimum(a[..., 1] + a[..., 3], b[..., 1] + b[..., 3])
                     - np.maximum(a[..., 1], b[..., 1]), 0, None)
        covers = iw * ih >= 0.5 * b[..., 2] * b[..., 3]
        group = covers.sum(axis=1) >= 2
        for i in np.flatnonzero(group):  # fits the group's union box better than anyone?
            people = gt[covers[i]]
            lo = people[:, :2].min(axis=0)
            hi = (people[:, :2] + people[:, 2:]).max(axis=0)
            union = np.concatenate([lo, hi - lo])
            group[i] = iou_xywh(d[i], union) > iou_xywh(d[i], people).max()
        merged = int(np.count_nonzero(group))
        people_in_merged = int(np.count_nonzero(covers[group].any(axis=0)))
    return MatchCounts(tp=tp, fp=int(unmatched.sum()), fn=len(gt) - tp, merged=merged,
                       people_in_merged=people_in_merged, n_det=len(d), n_gt=len(gt))
