"""Perturbed copies of a MOTChallenge sequence: what a new detector or camera changes.

A default chosen on a few sequences of one detector holds elsewhere only if it holds
when the detections change the way another detector's or camera's would. Each
:data:`KINDS` entry is a deterministic, seeded change of a sequence's public detections
``det.txt`` (and, for the frame rate, of its frames and ground truth):

* score maps — ``probability`` (the logistic of the scores standardised by their median
  and interquartile range), ``logit`` (that probability's logit), ``rank`` (each score's
  rank over the sequence, divided by the count), ``affine`` (``3 s − 7``) and ``power``
  (``(s − min + 1)^0.5``): strictly increasing maps, so a tracker whose decisions read
  scores only through what they say about the detections gives the same tracks;
* ``fps/2``, ``fps/3`` — every second or third frame kept (frames renumbered, the
  frame rate divided), starting at frame ``1 + seed mod step``: each seed below the step
  keeps another share of the frames;
* ``drop`` — 20 % of the detections removed;
* ``jitter`` — each box's centre and size moved by a Gaussian of 5 % of its size;
* ``false-positives`` — 20 % more detections, false: boxes (size and place) and scores
  drawn from the sequence's own detections of other frames, shifted by one to two
  boxes so they mark nobody, kept inside the image;
* ``low-scores`` — the same detector run at a lower threshold, as a user dumps a
  probability detector's boxes (YOLO, RT-DETR, Faster R-CNN at a confidence of 0.1 or
  less): as many more detections as it had, false (placed as ``false-positives``'), each
  scored below every score it gave (by up to half their range), so a share of the
  detections is no longer a share of the objects;
* ``high-scores`` — the same detector run at a higher threshold: its detections below
  the 0.4 quantile of its scores removed, so the share it keeps holds fewer of its false
  detections than before;
* ``shifted`` — every box 10 % taller, moved down by 5 % of its height and right by
  3 % of its width (another detector's box convention).

:func:`perturb_sequence` writes a sequence folder (``det/det.txt``, ``gt/gt.txt``,
``seqinfo.ini`` and ``img1/`` links to the original frames) that the toolkit and the
peer trackers read as they read the original.

>>> import numpy as np
>>> det = np.array([[1, -1, 10, 10, 20, 40, 0.9], [2, -1, 12, 10, 20, 40, 0.2]])
>>> perturb_detections(det, "rank", np.random.default_rng(0))[:, 6].tolist()
[1.0, 0.5]
"""

from __future__ import annotations

import configparser
import os
from pathlib import Path

import numpy as np

__all__ = ["KINDS", "SCORE_KINDS", "score_transform", "perturb_detections", "keep_frames",
           "frame_step", "perturb_sequence"]

#: the strictly increasing score maps
SCORE_KINDS = ("probability", "logit", "rank", "affine", "power")
#: every perturbation kind, by name (``"none"``: the sequence as it is)
KINDS = ("none",) + SCORE_KINDS + ("fps/2", "fps/3", "drop", "jitter", "false-positives",
                                   "low-scores", "high-scores", "shifted")

#: the frame-rate kinds: every ``step``-th frame kept
FRAME_STEPS = {"fps/2": 2, "fps/3": 3}


def frame_step(kind: str) -> int:
    """Every how many frames a kind keeps one: 2 or 3 for a frame rate divided, else 1
    (also the number of shares of the frames it can keep, :func:`perturb_sequence`'s
    seed picking one)."""
    return FRAME_STEPS.get(kind, 1)


DROP = 0.2
JITTER = 0.05
FALSE_POSITIVES = 0.2
#: ``low-scores``: extra false detections per detection, and how far below the lowest
#: score they go (a share of the scores' range)
LOW_SCORES = (1.0, 0.5)
#: ``high-scores``: the quantile of the scores below which detections are removed
HIGH_SCORES = 0.4
SHIFT = (0.03, 0.05, 1.1)  # right (of the width), down (of the height), height scale


def score_transform(scores: np.ndarray, kind: str) -> np.ndarray:
    """``scores`` through the strictly increasing map ``kind`` (:data:`SCORE_KINDS`).

    The maps are strictly increasing in exact arithmetic; in floating point the logistic
    is kept away from saturation by standardising first, so distinct scores stay
    distinct for the shared detectors' ranges."""
    s = np.asarray(scores, dtype=float)
    if kind not in SCORE_KINDS:
        raise ValueError(f"unknown score map {kind!r} (choose from {SCORE_KINDS})")
    if s.size == 0:
        return s.copy()
    if kind == "affine":
        return 3.0 * s - 7.0
    if kind == "power":
        return np.sqrt(s - s.min() + 1.0)
    if kind == "rank":
        order = np.sort(s)
        return np.searchsorted(order, s, side="right") / s.size
    q1, med, q3 = np.quantile(s, [0.25, 0.5, 0.75])
    z = (s - med) / max(float(q3 - q1), 1e-12)
    p = 0.5 * (1.0 + np.tanh(0.5 * z))
    return p if kind == "probability" else z  # logit(p) = z, without the round trip


def perturb_detections(det: np.ndarray, kind: str, rng: np.random.Generator,
                       image_size: tuple[float, float] | None = None) -> np.ndarray:
    """Rows of ``det.txt`` (``frame, id, x, y, w, h, score, ...``) perturbed by ``kind``
    (any of :data:`KINDS` but the frame rates, :func:`keep_frames`). ``image_size``
    ``(width, height)``: the false positives are kept inside it, as a detector's are."""
    d = np.array(det, dtype=float, copy=True)
    if d.ndim != 2 or d.shape[1] < 7:
        raise ValueError(f"detections need at least 7 columns, got shape {d.shape}")
    if kind == "none":
        return d
    if kind in SCORE_KINDS:
        d[:, 6] = score_transform(d[:, 6], kind)
        return d
    if kind == "drop":
        return d[rng.random(len(d)) >= DROP]
    if kind == "high-scores":
        return d[d[:, 6] >= np.quantile(d[:, 6], HIGH_SCORES)] if len(d) else d
    if kind == "jitter":
        w, h = d[:, 4].copy(), d[:, 5].copy()
        cx, cy = d[:, 2] + w / 2 + rng.normal(0, JITTER, len(d)) * w, \
            d[:, 3] + h / 2 + rng.normal(0, JITTER, len(d)) * h
        w = np.maximum(w * (1 + rng.normal(0, JITTER, len(d))), 1.0)
        h = np.maximum(h * (1 + rng.normal(0, JITTER, len(d))), 1.0)
        d[:, 2], d[:, 3], d[:, 4], d[:, 5] = cx - w / 2, cy - h / 2, w, h
        return d
    if kind in ("false-positives", "low-scores"):
        n = int(round((FALSE_POSITIVES if kind == "false-positives" else LOW_SCORES[0])
                      * len(d)))
        if n == 0 or len(d) < 2:
            return d
        frames = d[:, 0].astype(int)
        src = rng.integers(0, len(d), n)  # size, place and score of one of its detections
        frame = frames[rng.integers(0, len(d), n)]  # ... put in a random frame
        fp = d[src].copy()
        fp[:, 0] = frame
        fp[:, 1] = -1
        # moved by one to two boxes in a random direction, so it marks nobody there
        angle = rng.uniform(0, 2 * np.pi, n)
        dist = rng.uniform(1.0, 2.0, n)
        fp[:, 2] += np.cos(angle) * dist * fp[:, 4]
        fp[:, 3] += np.sin(angle) * dist * fp[:, 5]
        if image_size is not None:  # 1-based top-left corners, the box inside the image
            w, h = float(image_size[0]), float(image_size[1])
            fp[:, 2] = np.clip(fp[:, 2], 1.0, np.maximum(w - fp[:, 4], 1.0))
            fp[:, 3] = np.clip(fp[:, 3], 1.0, np.maximum(h - fp[:, 5], 1.0))
        if kind == "false-positives":  # scored as its own detections are
            fp[:, 6] = d[rng.integers(0, len(d), n), 6]
        else:  # below every score it gave
            s = d[:, 6]
            span = float(np.ptp(s)) or max(abs(float(s.min())), 1.0)
            fp[:, 6] = s.min() - rng.uniform(0.0, LOW_SCORES[1], n) * span - 1e-9 * span
        out = np.concatenate([d, fp])
        return out[np.argsort(out[:, 0], kind="stable")]
    if kind == "shifted":
        dx, dy, scale = SHIFT
        d[:, 2] += dx * d[:, 4]
        d[:, 3] += dy * d[:, 5] - (scale - 1.0) * d[:, 5] / 2
        d[:, 5] *= scale
        return d
    raise ValueError(f"unknown perturbation {kind!r} (choose from {KINDS})")


def keep_frames(rows: np.ndarray, step: int, num_frames: int, phase: int = 0) -> np.ndarray:
    """MOT rows of the frames ``1 + phase, 1 + phase + step, …`` (≤ ``num_frames``;
    ``0 <= phase < step``), renumbered ``1, 2, …``."""
    if not 0 <= phase < step:
        raise ValueError(f"keep_frames: phase must be in [0, {step}), got {phase!r}")
    r = np.array(rows, dtype=float, copy=True)
    f = r[:, 0].astype(int)
    keep = ((f - 1 - phase) % step == 0) & (f > phase) & (f <= num_frames)
    r = r[keep]
    r[:, 0] = (r[:, 0].astype(int) - 1 - phase) // step + 1
    return r


def _read_rows(path: Path) -> np.ndarray:
    rows = [line.replace(" ", "").split(",") for line in
            path.read_text(encoding="utf-8-sig").splitlines() if line.strip()]
    width = max((len(r) for r in rows), default=7)
    out = np.full((len(rows), width), np.nan)
    for i, r in enumerate(rows):
        out[i, :len(r)] = [float(v) for v in r]
    return out


def _write_rows(path: Path, rows: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [",".join(f"{v:.10g}" for v in row if not np.isnan(v)) for row in rows]
    path.write_text("".join(line + "\n" for line in lines))


def perturb_sequence(source: str | Path, out: str | Path, kind: str, seed: int = 0,
                     frames: list[Path] | None = None) -> Path:
    """Write ``source`` (a MOTChallenge folder with ``det/det.txt``, ``gt/gt.txt`` and
    ``seqinfo.ini``) perturbed by ``kind`` to the folder ``out``; returns ``out``.

    ``frames``: the source's image files in order (default: ``img1/`` as ``seqinfo.ini``
    names it), linked from ``out/img1/`` under their new numbers. The detections are
    perturbed after the frame rate is changed, with ``numpy.random.default_rng(seed)``; a
    frame rate keeps the frames from ``1 + seed mod step`` on.
    """
    src, dst = Path(source), Path(out)
    if kind not in KINDS:
        raise ValueError(f"unknown perturbation {kind!r} (choose from {KINDS})")
    ini = configparser.ConfigParser(interpolation=None)
    ini.optionxform = str
    ini.read_string((src / "seqinfo.ini").read_text(encoding="utf-8-sig"))
    info = ini["Sequence"]
    n = int(info["seqLength"])
    ext = info.get("imExt", ".jpg")
    if frames is None:
        frames = [src / info.get("imDir", "img1") / f"{k:06d}{ext}" for k in range(1, n + 1)]
    if len(frames) < n:
        raise ValueError(f"{src}: {len(frames)} frames for a sequence of {n}")
    step = frame_step(kind)
    phase = int(seed) % step
    det = keep_frames(_read_rows(src / "det" / "det.txt"), step, n, phase)
    gt = keep_frames(_read_rows(src / "gt" / "gt.txt"), step, n, phase)
    if step == 1:
        size = ((float(info["imWidth"]), float(info["imHeight"]))
                if "imWidth" in info and "imHeight" in info else None)
        det = perturb_detections(det, kind, np.random.default_rng(seed), image_size=size)
    kept = frames[phase:n:step]
    _write_rows(dst / "det" / "det.txt", det)
    _write_rows(dst / "gt" / "gt.txt", gt)
    info["seqLength"] = str(len(kept))
    info["frameRate"] = f"{float(info.get('frameRate', 25)) / step:g}"
    info["imDir"] = "img1"
    info["imExt"] = Path(kept[0]).suffix if kept else ext
    img = dst / "img1"
    img.mkdir(parents=True, exist_ok=True)
    for k, f in enumerate(kept, start=1):
        link = img / f"{k:06d}{info['imExt']}"
        if link.is_symlink() or link.exists():
            link.unlink()
        os.symlink(Path(f).resolve(), link)
    with open(dst / "seqinfo.ini", "w", encoding="utf-8") as fh:
        ini.write(fh, space_around_delimiters=False)
    return dst
