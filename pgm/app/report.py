"""``pgm report DIR``: one self-contained HTML page about the runs under a folder.

``DIR`` is one run folder (``tracks.txt``, ``metrics.json``, ``run.json``, ``model.json``
as ``pgm track`` writes them) or any folder holding many (at any depth, e.g.
``runs/<seq>/<model>/<seed>/`` as ``pgm bench`` writes them). :func:`write_report` finds
every folder holding a ``run.json`` or a ``metrics.json``, reads them and writes

* ``DIR/report.html`` — readable without JavaScript or network: inline CSS, every image a
  PNG embedded as a ``data:image/png;base64,`` URI;
* ``DIR/report_files/*.png`` — the same images as files (earlier ``*.png`` there are
  removed first).

Contents
--------
* a summary (one row per sequence and model);
* single-object runs: the OTB success plot (fraction of scored frames with IoU above
  each threshold, success AUC in the legend) and precision plot (fraction with centre
  error at most each distance, precision at 20 px in the legend), per sequence and
  overall (the mean of the per-sequence curves, as the OTB toolkit averages them);
* multi-target runs: bars of MOTA, IDF1, HOTA, MOTP, DetA, AssA and of the mean OSPA
  values per sequence and model (and their mean over sequences), and the per-frame OSPA
  and cardinality (truth against estimate) of each sequence from the ``per_frame``
  series of ``metrics.json``;
* frames per second of inference (``run.json``'s ``fps``: decoding, detection and
  drawing excluded);
* the factor graph of each model, drawn from its ``model.json``;
* every scalar metric, one table per sequence (rows: metrics; columns: models);
* every run found, and those left out (unfinished: ``run.json`` says
  ``"complete": false``).

Grouping
--------
A run's *sequence* is the last component of ``run.json``'s ``source`` (the folder above
``img``/``img1``/``imgs`` when the source is the image folder itself, the file name
without its suffix for a video); its *model* is ``run.json``'s ``model`` (the graph's
name). Runs sharing a sequence and model are the seeds of one configuration and are
averaged: the tables show ``mean ± standard deviation`` over seeds (``n - 1`` in the
denominator), the plots the mean curve with the seeds' range shaded. Runs of one
sequence and model that differ in length (``run.json``'s ``frames``) or settings
(particles, camera motion, dropped frames, ``model.json``'s engine settings) are not
seeds of one configuration: each gets the settings that differ in its label
(``colour-pf (50 frames)``), a row of its own, and the page and a warning say so. When
runs of one model name sit in differently named parent folders (two configurations of
one model, e.g. ``runs/<seq>/phd/`` and ``runs/<seq>/phd-scores/``), the parent
folder's name tells them apart.

Bad input — ``DIR`` missing or not a folder, no run under it, no finished run, a
``run.json`` or ``metrics.json`` that is not a JSON object, a malformed per-frame
series — is an :class:`~pgm.core.errors.InputError` naming the problem. A ``model.json``
that cannot be drawn is noted on the page, not an error.
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import json
import logging
import math
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError, one_line
from pgm.io.outputs import write_text

__all__ = ["Run", "Group", "find_runs", "load_run", "group_runs", "split_configurations",
           "write_report",
           "add_parser", "cmd_report", "COMMANDS", "REPORT_NAME", "FILES_DIR"]

REPORT_NAME = "report.html"
FILES_DIR = "report_files"

#: metric keys shown with a friendlier name (others show their key)
METRIC_NAMES = {
    "success_auc": "success AUC", "precision_at_20": "precision @ 20 px",
    "mean_iou": "mean IoU", "mean_centre_error": "mean centre error (px)",
    "median_centre_error": "median centre error (px)", "n_frames": "frames scored",
    "n_missing": "frames without a box", "fps": "frames per second",
    "mota": "MOTA", "motp": "MOTP (IoU)", "idf1": "IDF1", "idp": "IDP", "idr": "IDR",
    "hota": "HOTA", "deta": "DetA", "assa": "AssA", "loca": "LocA",
    "id_switches": "ID switches", "fragmentations": "fragmentations",
    "fp": "false positives", "fn": "false negatives", "tp": "true positives",
    "mostly_tracked": "mostly tracked", "partially_tracked": "partially tracked",
    "mostly_lost": "mostly lost", "ospa2": "OSPA⁽²⁾ (px)", "ospa2_window": "OSPA⁽²⁾ window",
    "mean_abs_cardinality_error": "|cardinality error|", "error_rate": "error rate",
    "num_gt": "ground-truth boxes", "num_pred": "predicted boxes",
    "num_frames": "frames scored", "detector_fps": "detector frames per second",
    "run.frames": "frames processed", "num_gt_ignored": "ground-truth rows ignored",
    "num_pred_ignored": "predictions on ignore regions",
    "confidence.calibration.n": "confidence: frames calibrated",
    "confidence.calibration.ece": "confidence: expected calibration error",
    "confidence.calibration.brier": "confidence: Brier score",
    "confidence.calibration.mean_confidence": "confidence: mean",
    "confidence.calibration.hit_rate": "confidence: hit rate (IoU ≥ 0.5)",
}
#: scores in [0, 1] drawn as MOT bars (higher is better)
MOT_SCORES = (("MOTA", "mota"), ("IDF1", "idf1"), ("HOTA", "hota"), ("MOTP", "motp"),
              ("DetA", "deta"), ("AssA", "assa"))
_IMAGE_DIRS = ("img", "img1", "imgs")
_log = logging.getLogger("pgm")
_VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".mpg", ".mpeg", ".m4v", ".wmv")


# --------------------------------------------------------------------------- reading


def _read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; anything else is an :class:`InputError`."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or one_line(exc)}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path} is corrupt: not UTF-8 text") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is corrupt: not valid JSON ({exc.msg} at line "
                         f"{exc.lineno})") from None
    except RecursionError:
        raise InputError(f"{path} is corrupt: JSON nested too deeply") from None
    if not isinstance(data, dict):
        raise InputError(f"{path} is corrupt: expected a JSON object, found "
                         f"{type(data).__name__}")
    return data


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _numbers(value: Any, where: str) -> np.ndarray:
    """A 1-D float array from a JSON list (``None`` → NaN); an :class:`InputError`
    naming ``where`` otherwise."""
    if not isinstance(value, list) or not all(v is None or _is_number(v) for v in value):
        raise InputError(f"{where} is corrupt: expected a list of numbers")
    return np.array([np.nan if v is None else float(v) for v in value], dtype=float)


def _sequence_name(source: Any, folder: Path) -> str:
    if not isinstance(source, str) or not source.strip():
        return folder.name or "unknown"
    p = Path(source.rstrip("/\\"))
    if p.name.lower() in _IMAGE_DIRS and p.parent.name:
        return p.parent.name
    if p.suffix.lower() in _VIDEO_SUFFIXES:
        return p.stem
    return p.name or source


@dataclass
class Run:
    """One run folder as read by :func:`load_run`.

    Attributes
    ----------
    path : Path
        The folder.
    rel : str
        Its path relative to the report's root (``"."`` for the root itself).
    info : dict
        ``run.json`` (empty when the folder has none).
    metrics : dict or None
        ``metrics.json`` (None when the run had no ground truth).
    sequence, model : str
        The names it is grouped by (see the module docstring).
    label : str
        The model's name in the report (``model``, or told apart by the parent folder).
    """

    path: Path
    rel: str
    info: dict[str, Any]
    metrics: dict[str, Any] | None
    sequence: str
    model: str
    label: str = ""

    @property
    def complete(self) -> bool:
        """False when ``run.json`` says the run did not finish."""
        return bool(self.info.get("complete", True)) if self.info else self.metrics is not None

    @property
    def kind(self) -> str:
        """``"single"`` (OTB metrics), ``"multi"`` (MOT metrics) or ``"unscored"``."""
        m = self.metrics or {}
        if "mota" in m:
            return "multi"
        if "success_auc" in m or "ious" in m:
            return "single"
        return "unscored"

    @property
    def fps(self) -> float | None:
        """Frames per second of inference (``run.json``, else ``metrics.json``)."""
        for src in (self.info, self.metrics or {}):
            v = src.get("fps")
            if _is_number(v) and math.isfinite(v):
                return float(v)
        return None

    @property
    def model_file(self) -> Path | None:
        """``model.json`` when the folder has one."""
        p = self.path / "model.json"
        return p if p.is_file() else None


def find_runs(root: str | Path) -> list[Path]:
    """Every folder under ``root`` (itself included, any depth, symbolic links not
    followed, hidden folders and ``report_files`` skipped) holding a ``run.json`` or a
    ``metrics.json``, sorted.

    Raises
    ------
    InputError
        ``root`` missing or not a folder.
    """
    base = Path(root)
    if not base.exists():
        raise InputError(f"{base}: no such folder")
    if not base.is_dir():
        raise InputError(f"{base} is not a folder (give a run folder or a folder of runs)")
    found = []
    for dirpath, dirnames, filenames in os.walk(base):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".") and d != FILES_DIR)
        if "run.json" in filenames or "metrics.json" in filenames:
            found.append(Path(dirpath))
    return sorted(found)


def load_run(folder: str | Path, root: str | Path | None = None) -> Run:
    """Read one run folder (``run.json``, ``metrics.json``; ``model.json``'s name when
    ``run.json`` has none).

    Raises
    ------
    InputError
        A ``run.json`` or ``metrics.json`` that is not a JSON object.
    """
    path = Path(folder)
    info = _read_json(path / "run.json") if (path / "run.json").is_file() else {}
    metrics = _read_json(path / "metrics.json") if (path / "metrics.json").is_file() else None
    model = info.get("model")
    if not isinstance(model, str) or not model:
        model = None
        if (path / "model.json").is_file():
            try:
                name = json.loads((path / "model.json").read_text(encoding="utf-8")).get("name")
                model = name if isinstance(name, str) and name else None
            except (OSError, ValueError, AttributeError, RecursionError):
                model = None
        model = model or path.name or "model"
    rel = "." if root is None else (os.path.relpath(path, root) or ".")
    return Run(path, rel, info, metrics, _sequence_name(info.get("source"), path), model)


@dataclass
class Group:
    """The runs of one (sequence, model label): the seeds of one configuration."""

    sequence: str
    label: str
    runs: list[Run] = field(default_factory=list)

    @property
    def kind(self) -> str:
        """``"multi"`` if any run has MOT metrics, else ``"single"`` if any has OTB
        metrics, else ``"unscored"``."""
        kinds = {r.kind for r in self.runs}
        return "multi" if "multi" in kinds else "single" if "single" in kinds else "unscored"

    def scored(self) -> list[Run]:
        """The runs whose metrics are of the group's kind."""
        return [r for r in self.runs if r.kind == self.kind]


def _assign_labels(runs: list[Run]) -> None:
    parents: dict[str, set[str]] = {}
    for r in runs:
        parents.setdefault(r.model, set()).add(_parent_name(r))
    for r in runs:
        parent = _parent_name(r)
        if len(parents[r.model]) <= 1 or not parent:
            r.label = r.model
        else:
            r.label = parent if r.model in parent else f"{r.model} ({parent})"


def _parent_name(r: Run) -> str:
    """The name of the folder above the run, relative to the root ('' at the root)."""
    parent = Path(r.rel).parent
    return "" if r.rel == "." or str(parent) in ("", ".") else parent.name


#: ``run.json`` fields that make two runs of one model different configurations (not
#: seeds of one): how many frames were tracked and the settings the runner recorded
CONFIG_FIELDS = ("frames", "num_particles", "camera_motion", "dropped_frames")


def _config(run: Run) -> dict[str, str]:
    """What a run was run with, each value as compact JSON: the :data:`CONFIG_FIELDS` of
    ``run.json`` (``frames`` from ``metrics.json``'s ``n_frames`` when it has none) and
    the engine settings of ``model.json``."""
    out = {k: run.info[k] for k in CONFIG_FIELDS if k in run.info}
    if "frames" not in out and _is_number((run.metrics or {}).get("n_frames")):
        out["frames"] = run.metrics["n_frames"]
    if run.model_file is not None:
        try:
            meta = json.loads(run.model_file.read_text(encoding="utf-8")).get("meta")
            engine = meta.get("engine") if isinstance(meta, dict) else None
        except (OSError, ValueError, AttributeError, RecursionError):
            engine = None
        if isinstance(engine, dict):
            out["engine"] = engine
    return {k: json.dumps(v, sort_keys=True, separators=(",", ":")) for k, v in out.items()}


def _describe(key: str, text: str) -> str:
    """One differing setting, in words: ``50 frames``, ``particles 100``."""
    value = json.loads(text)
    if key == "frames":
        return f"{value} frames"
    if key == "num_particles" and isinstance(value, dict) and len(set(
            map(str, value.values()))) == 1:
        value = next(iter(value.values()))
    if key == "dropped_frames" and isinstance(value, list):
        return f"{len(value)} frames dropped"
    name = {"num_particles": "particles", "camera_motion": "camera motion"}.get(key, key)
    if isinstance(value, (dict, list)):
        value = text
    return f"{name} {value}"


def split_configurations(runs: list[Run]) -> list[str]:
    """Tell apart runs of one sequence and label that are not seeds of one configuration
    (a 300-frame and a 50-frame run; other particle counts or engine settings): each
    such run's label gets the settings that differ, e.g. ``colour-pf (50 frames)``, so
    they are separate rows, never averaged. Returns one line per (sequence, label) split.
    """
    by_key: dict[tuple[str, str], list[Run]] = {}
    for r in runs:
        by_key.setdefault((r.sequence, r.label), []).append(r)
    notes = []
    for (sequence, label), members in sorted(by_key.items()):
        configs = [_config(r) for r in members]
        keys = sorted({k for c in configs for k in c})
        differing = [k for k in keys if len({c.get(k) for c in configs}) > 1]
        if not differing:
            continue
        if "engine" in differing:  # name the engine settings that differ, not all of them
            engines = [json.loads(c.get("engine", "{}")) for c in configs]
            sub = sorted({k for e in engines for k in e
                          if len({json.dumps(e.get(k), sort_keys=True) for e in engines}) > 1})
            for c, e in zip(configs, engines, strict=True):
                c.update({f"engine.{k}": json.dumps(e.get(k), sort_keys=True) for k in sub})
            differing = [k for k in differing if k != "engine"] + [f"engine.{k}" for k in sub]
        for r, c in zip(members, configs, strict=True):
            words = [_describe(k, c[k]) for k in differing if k in c]
            r.label = f"{label} ({', '.join(words)})" if words else label
        notes.append(f"{sequence}, {label}: {len(members)} runs differ in "
                     f"{', '.join(k.replace('_', ' ') for k in differing)}; shown as "
                     f"{len({r.label for r in members})} rows, not averaged")
    return notes


def group_runs(runs: Iterable[Run]) -> list[Group]:
    """Runs grouped by (sequence, label), sorted; labels assigned on the way (runs of one
    label that differ in length or settings get distinct labels:
    :func:`split_configurations`)."""
    runs = list(runs)
    _assign_labels(runs)
    split_configurations(runs)
    return _group(runs)


def _group(runs: list[Run]) -> list[Group]:
    groups: dict[tuple[str, str], Group] = {}
    for r in runs:
        groups.setdefault((r.sequence, r.label), Group(r.sequence, r.label)).runs.append(r)
    return [groups[k] for k in sorted(groups)]


# --------------------------------------------------------------------------- numbers


def _flatten(d: dict[str, Any], prefix: str = "") -> Iterable[tuple[str, float | None]]:
    """Scalar values of a nested dict (lists, ``per_frame`` and ``thresholds`` skipped;
    JSON integers stay ``int``, so counts print as counts)."""
    for k, v in d.items():
        key = f"{prefix}{k}"
        if _is_number(v):
            yield key, v if math.isfinite(v) else None
        elif v is None:
            yield key, None
        elif isinstance(v, dict) and k not in ("per_frame", "thresholds"):
            yield from _flatten(v, key + ".")


def _scalars(run: Run) -> dict[str, float | None]:
    out = dict(_flatten(run.metrics or {}))
    if "fps" not in out and run.fps is not None:
        out["fps"] = run.fps
    frames = run.info.get("frames")
    if _is_number(frames):
        out["run.frames"] = frames
    return out


@dataclass
class Stat:
    """Mean and standard deviation over seeds (``std`` None for one value)."""

    mean: float | None
    std: float | None
    n: int
    integer: bool


def _stat(values: list[float | None]) -> Stat:
    kept = [v for v in values if v is not None]
    if not kept:
        return Stat(None, None, 0, False)
    vals = np.array(kept, dtype=float)
    std = float(np.std(vals, ddof=1)) if vals.size > 1 else None
    return Stat(float(vals.mean()), std, int(vals.size),
                all(isinstance(v, (int, np.integer)) for v in kept))


def _group_stats(group: Group) -> dict[str, Stat]:
    per_run = [_scalars(r) for r in group.runs]
    keys: list[str] = []
    for s in per_run:
        keys += [k for k in s if k not in keys]
    return {k: _stat([s.get(k) for s in per_run]) for k in keys}


def _fmt(value: float | None, integer: bool = False) -> str:
    if value is None or not math.isfinite(value):
        return "–"
    if integer and value == round(value) and abs(value) < 1e15:
        return str(int(round(value)))
    if abs(value) >= 1000:
        return f"{value:.0f}"
    return f"{value:.4g}"


def _fmt3(value: float | None) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{value:.3f}"


def _fmt_stat(s: Stat) -> str:
    """``mean`` (4 significant digits), ``± std`` (2) when the runs differ."""
    same = s.std is None or s.std == 0.0
    text = _fmt(s.mean, s.integer and same)
    if not same:
        text += f" ± {s.std:.0f}" if s.std >= 10 else f" ± {s.std:.2g}"
    return text


def _curve(run: Run, kind: str) -> tuple[np.ndarray, np.ndarray] | None:
    """A run's success (``kind='success'``) or precision curve: thresholds and values
    (stored curves, else computed from the per-frame IoU / centre errors)."""
    from pgm.evaluation import single_object as so

    m = run.metrics or {}
    where = run.path / "metrics.json"
    stored = m.get(f"{kind}_curve")
    thresholds = (m.get("thresholds") or {}).get(kind) if isinstance(m.get("thresholds"),
                                                                      dict) else None
    if stored is not None and thresholds is not None:
        y = _numbers(stored, f"{where}: {kind}_curve")
        x = _numbers(thresholds, f"{where}: thresholds.{kind}")
        if x.size != y.size:
            raise InputError(f"{where} is corrupt: {kind}_curve has {y.size} values for "
                             f"{x.size} thresholds")
        return x, y
    per_frame = m.get("ious" if kind == "success" else "centre_errors")
    if per_frame is None:
        return None
    vals = _numbers(per_frame, f"{where}: {'ious' if kind == 'success' else 'centre_errors'}")
    if vals.size == 0:
        return None
    if kind == "success":
        return so.SUCCESS_THRESHOLDS, so.success_curve(np.nan_to_num(vals, nan=0.0))
    return so.PRECISION_THRESHOLDS, so.precision_curve(np.nan_to_num(vals, nan=np.inf))


def _mean_curve(runs: list[Run], kind: str) -> dict[str, Any] | None:
    curves = [c for c in (_curve(r, kind) for r in runs) if c is not None]
    if not curves:
        return None
    x = curves[0][0]
    ys = np.array([np.interp(x, cx, cy) if cx.size != x.size or np.any(cx != x) else cy
                   for cx, cy in curves])
    return {"x": x, "y": ys.mean(axis=0), "lo": ys.min(axis=0), "hi": ys.max(axis=0),
            "n": len(curves)}


def _series(runs: list[Run], key: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Frame numbers and the mean over runs of the per-frame series ``key``."""
    table: dict[int, list[float]] = {}
    for r in runs:
        pf = (r.metrics or {}).get("per_frame")
        if not isinstance(pf, dict) or key not in pf:
            continue
        where = f"{r.path / 'metrics.json'}: per_frame"
        frames = _numbers(pf.get("frames"), f"{where}.frames")
        vals = _numbers(pf[key], f"{where}.{key}")
        if frames.size != vals.size:
            raise InputError(f"{where} is corrupt: {key} has {vals.size} values for "
                             f"{frames.size} frames")
        for f, v in zip(frames, vals, strict=True):
            table.setdefault(int(f), []).append(v)
    if not table:
        return None
    frames = np.array(sorted(table))
    with np.errstate(invalid="ignore"):
        mean = np.array([np.nanmean(table[f]) if np.any(np.isfinite(table[f])) else np.nan
                         for f in frames])
    return frames, mean


def _confidence_outcomes(run: Run) -> tuple[np.ndarray, np.ndarray] | None:
    """A run's confidence and outcome (IoU ≥ 0.5) at its scored frames, or None where
    its ``metrics.json`` holds no per-frame confidence."""
    from pgm.evaluation.calibration import confidence_outcomes

    m = run.metrics or {}
    conf = m.get("confidence")
    if not isinstance(conf, dict) or "values" not in conf or "ious" not in m:
        return None
    where = run.path / "metrics.json"
    values = _numbers(conf["values"], f"{where}: confidence.values")
    if np.any(~np.isfinite(values) | (values < 0) | (values > 1)):
        raise InputError(f"{where} is corrupt: confidence.values must lie in [0, 1]")
    try:
        c, hit = confidence_outcomes(_numbers(conf.get("frames"), f"{where}: confidence.frames"),
                                     values, _numbers(m.get("frames"), f"{where}: frames"),
                                     _numbers(m["ious"], f"{where}: ious"))
    except ValueError as exc:
        raise InputError(f"{where} is corrupt: {exc}") from None
    return (c, hit) if c.size else None


def _calibration(runs: list[Run]) -> dict[str, Any] | None:
    """The reliability of the confidence of ``runs`` (one model) pooled with every
    sequence weighted equally (its seeds share its weight), and the mean over sequences
    of each sequence's own ECE; None where no run has a confidence."""
    from pgm.evaluation.calibration import reliability, video_weights

    per_seq: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for r in runs:
        co = _confidence_outcomes(r)
        if co is not None:
            per_seq.setdefault(r.sequence, []).append(co)
    if not per_seq:
        return None
    # each sequence's seeds together: (confidence, outcome)
    joined = {q: tuple(np.concatenate(part) for part in zip(*cos, strict=True))
              for q, cos in per_seq.items()}
    c = np.concatenate([cy[0] for cy in joined.values()])
    y = np.concatenate([cy[1] for cy in joined.values()])
    who = np.concatenate([[q] * len(cy[0]) for q, cy in joined.items()])
    return {"pooled": reliability(c, y, weights=video_weights(who)), "sequences": len(joined),
            "runs": sum(map(len, per_seq.values())),
            "mean_sequence_ece": float(np.mean([reliability(*cy)["ece"]
                                                for cy in joined.values()]))}


# --------------------------------------------------------------------------- figures


class _Images:
    """PNG images written to ``report_files/`` and kept for embedding."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.names: set[str] = set()

    def _name(self, stem: str) -> str:
        base = re.sub(r"[^A-Za-z0-9._-]+", "-", stem).strip("-.") or "figure"
        name, k = f"{base}.png", 2
        while name in self.names:
            name, k = f"{base}-{k}.png", k + 1
        self.names.add(name)
        return name

    def save_figure(self, fig, stem: str) -> tuple[str, bytes]:
        """Render a matplotlib figure to PNG, write it; returns its file name and bytes."""
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
        data = buf.getvalue()
        name = self._name(stem)
        (self.folder / name).write_bytes(data)
        return name, data

    def path_for(self, stem: str) -> Path:
        """A fresh file path for an image written by someone else (the graph drawing)."""
        return self.folder / self._name(stem)


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def _colours(labels: list[str]) -> dict[str, Any]:
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return {label: cmap(i % 10) for i, label in enumerate(labels)}


def _otb_figure(entries: list[dict[str, Any]], title: str):
    """Success and precision plots side by side; ``entries``: label, colour, success,
    precision (mean curves), auc, p20, band (shade the seeds' range)."""
    fig = _figure(10.5, 4.0)
    ax_s, ax_p = fig.subplots(1, 2)
    for ax, curve, score in ((ax_s, "success", "auc"), (ax_p, "precision", "p20")):
        for e in sorted(entries, key=lambda e: -(e[score] or 0.0)):
            c = e[curve]
            if c is None:
                continue
            ax.plot(c["x"], c["y"], color=e["colour"], lw=2,
                    label=f"{e['label']} [{_fmt3(e[score])}]")
            if e["band"] and c["n"] > 1:
                ax.fill_between(c["x"], c["lo"], c["hi"], color=e["colour"], alpha=0.15, lw=0)
    ax_s.set(xlim=(0, 1), ylim=(0, 1.02), xlabel="overlap threshold (IoU)",
             ylabel="success rate", title=f"Success plot — {title}")
    ax_p.set(xlim=(0, 50), ylim=(0, 1.02), xlabel="location error threshold (px)",
             ylabel="precision", title=f"Precision plot — {title}")
    ax_p.axvline(20, color="#888", ls=":", lw=1)
    for ax, where, head in ((ax_s, "lower left", "success AUC"),
                            (ax_p, "lower right", "precision @ 20 px")):
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:  # not the 20 px marker alone
            ax.legend(loc=where, fontsize=8, title=head, title_fontsize=8)
    return fig


def _reliability_figure(entries: list[tuple[str, Any, dict[str, Any]]]):
    """Reliability diagram: per model (``entries``: label, colour, calibration), each
    confidence bin's hit rate against its mean confidence, marker area ∝ the bin's
    share; the diagonal is a calibrated confidence."""
    fig = _figure(5.5, 4.6)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], color="#888", ls="--", lw=1, label="calibrated")
    for label, colour, cal in entries:
        bins = cal["pooled"]["bins"]
        x = [b["confidence"] for b in bins]
        y = [b["hit_rate"] for b in bins]
        ax.plot(x, y, color=colour, lw=1.5,
                label=f"{label} [{_fmt3(cal['pooled']['ece'])}]")
        ax.scatter(x, y, s=[20 + 400 * b["share"] for b in bins], color=colour, alpha=0.7,
                   edgecolors="none")
    ax.set(xlim=(0, 1), ylim=(-0.02, 1.02), xlabel="confidence (bin mean)",
           ylabel="hit rate (IoU ≥ 0.5)", title="Reliability, sequences weighted equally")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, title="ECE", title_fontsize=8)
    return fig


def _ospa_keys(keys: Iterable[str]) -> list[str]:
    return [k for k in keys if k.startswith("ospa_") and not k.endswith(("_loc", "_card"))]


def _ospa_label(key: str) -> str:
    if key == "ospa2":
        return "OSPA⁽²⁾"
    parts = key[len("ospa_"):].split("_")
    return f"OSPA({','.join(p.replace('p', '.') for p in parts)})"


def _mot_figure(rows: list[tuple[str, Any, dict[str, Stat]]], title: str):
    """Bars of the MOT scores and mean OSPA values; ``rows``: (label, colour, stats)."""
    fig = _figure(10.5, 3.8)
    ax_s, ax_d = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2, 1]})
    width = 0.8 / max(len(rows), 1)
    dist_keys = []
    for _, _, stats in rows:
        dist_keys += [k for k in _ospa_keys(stats) + ["ospa2"] if k in stats
                      and k not in dist_keys]
    for i, (label, colour, stats) in enumerate(rows):
        for ax, keys in ((ax_s, [k for _, k in MOT_SCORES]), (ax_d, dist_keys)):
            x = np.arange(len(keys)) + (i - (len(rows) - 1) / 2) * width
            mean = [stats[k].mean if k in stats and stats[k].mean is not None else np.nan
                    for k in keys]
            err = [stats[k].std if k in stats and stats[k].std is not None else 0.0
                   for k in keys]
            ax.bar(x, mean, width, yerr=err if any(err) else None, color=colour,
                   label=label if ax is ax_s else None, capsize=2,
                   error_kw={"lw": 0.8})
    ax_s.set_xticks(np.arange(len(MOT_SCORES)), [n for n, _ in MOT_SCORES])
    ax_s.axhline(0, color="#444", lw=0.8)
    ax_s.set(ylim=(min(0.0, ax_s.get_ylim()[0]), 1.0), ylabel="score (higher is better)",
             title=f"MOT scores — {title}")
    ax_d.set_xticks(np.arange(len(dist_keys)), [_ospa_label(k) for k in dist_keys])
    ax_d.set(ylabel="px (lower is better)", title="mean set distances")
    for ax in (ax_s, ax_d):
        ax.grid(axis="y", alpha=0.3)
    ax_s.legend(fontsize=8, loc="upper right", ncols=min(len(rows), 3))
    return fig


def _per_frame_figure(groups: list[Group], colours: dict[str, Any], title: str):
    """Per-frame OSPA (one panel per setting) and cardinality of one sequence."""
    keys: list[str] = []
    for g in groups:
        for r in g.scored():
            pf = (r.metrics or {}).get("per_frame")
            if isinstance(pf, dict):
                keys += [k for k in _ospa_keys(pf) + ["ospa2"] if k in pf and k not in keys]
    if not keys:
        return None
    fig = _figure(10.5, 1.9 * (len(keys) + 1) + 0.4)
    axes = fig.subplots(len(keys) + 1, 1, sharex=True)
    gt_done = False
    for g in groups:
        runs = g.scored()
        colour = colours[g.label]
        for ax, key in zip(axes[:-1], keys, strict=True):
            s = _series(runs, key)
            if s is not None:
                ax.plot(s[0], s[1], color=colour, lw=1.2, label=g.label)
        est = _series(runs, "pred_cardinality")
        if not gt_done:
            gt = _series(runs, "gt_cardinality")
            if gt is not None:
                axes[-1].step(gt[0], gt[1], where="mid", color="black", lw=2.2,
                              label="ground truth")
                gt_done = True
        if est is not None:
            axes[-1].step(est[0], est[1], where="mid", color=colour, lw=1.2,
                          label=f"{g.label} (estimate)")
    for ax, key in zip(axes[:-1], keys, strict=True):
        ax.set_ylabel(f"{_ospa_label(key)} px")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"Per-frame OSPA and cardinality — {title}")
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set(ylabel="targets", xlabel="frame")
    axes[-1].grid(alpha=0.3)
    axes[-1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig


def _fps_figure(rows: list[tuple[str, Any, Stat]]):
    """Horizontal bars of frames per second; ``rows``: (text, colour, stat)."""
    fig = _figure(9.0, 0.32 * len(rows) + 1.3)
    ax = fig.subplots()
    y = np.arange(len(rows))[::-1]
    means = np.array([s.mean for _, _, s in rows], dtype=float)
    err = [s.std or 0.0 for _, _, s in rows]
    ax.barh(y, means, xerr=err if any(err) else None, color=[c for _, c, _ in rows],
            capsize=2, error_kw={"lw": 0.8})
    ax.set_yticks(y, [t for t, _, _ in rows], fontsize=8)
    if means.size and means.min() > 0 and means.max() / means.min() > 50:
        ax.set_xscale("log")
    for yi, m, e in zip(y, means, err, strict=True):
        ax.text(m + e, yi, f"  {m:.0f}" if m >= 100 else f"  {m:.3g}", va="center",
                fontsize=8)
    if ax.get_xscale() == "linear":
        ax.set_xlim(0, float(np.max(means + np.asarray(err))) * 1.12)
    ax.set(xlabel="frames per second (inference only)", title="Speed")
    ax.grid(axis="x", alpha=0.3)
    return fig


# --------------------------------------------------------------------------- HTML

_CSS = """
:root { --ink: #1f2328; --muted: #59636e; --line: #d1d9e0; --band: #f6f8fa;
        --accent: #0969da; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto,
       "Helvetica Neue", Arial, sans-serif; color: var(--ink); background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 24px 28px 64px; }
header h1 { margin: 0 0 4px; font-size: 28px; }
.meta { color: var(--muted); margin: 0 0 8px; }
h2 { margin: 40px 0 12px; padding-bottom: 6px; border-bottom: 1px solid var(--line);
     font-size: 22px; }
h3 { margin: 28px 0 8px; font-size: 17px; }
a { color: var(--accent); text-decoration: none; }
a:hover { text-decoration: underline; }
nav ol { margin: 4px 0; padding-left: 22px; columns: 2; }
figure { margin: 12px 0 20px; padding: 10px; border: 1px solid var(--line);
         border-radius: 6px; background: #fff; }
figure img { display: block; max-width: 100%; height: auto; margin: 0 auto; }
figcaption { color: var(--muted); font-size: 13px; margin-top: 6px; }
.graphs { display: grid; grid-template-columns: repeat(auto-fill, minmax(340px, 1fr));
          gap: 12px; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; margin: 8px 0 16px; font-size: 13.5px; }
th, td { padding: 4px 10px; border-bottom: 1px solid var(--line); text-align: right;
         white-space: nowrap; }
th { background: var(--band); font-weight: 600; }
th:first-child, td:first-child, td.text, th.text { text-align: left; }
tbody tr:nth-child(even) { background: #fbfcfd; }
td code, .key { color: var(--muted); font-size: 12px; }
.note { color: var(--muted); font-size: 13.5px; }
.warn { color: #9a6700; }
details { margin: 8px 0; }
summary { cursor: pointer; color: var(--accent); }
footer { margin-top: 48px; color: var(--muted); font-size: 13px;
         border-top: 1px solid var(--line); padding-top: 12px; }
"""


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"


def _img(name: str, data: bytes, alt: str, caption: str | None = None) -> str:
    src = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    cap = f"<figcaption>{caption}</figcaption>" if caption else ""
    return (f'<figure><img src="{src}" alt="{_e(alt)}" data-file="{FILES_DIR}/{_e(name)}">'
            f"{cap}</figure>")


def _table(head: list[str], rows: list[list[str]], text_cols: int = 1) -> str:
    """An HTML table; cells are already-escaped HTML; the first ``text_cols`` columns
    are left-aligned."""
    left = ' class="text"'

    def cells(tag: str, values: list[str]) -> str:
        return "".join(f"<{tag}{left if i < text_cols else ''}>{v}</{tag}>"
                       for i, v in enumerate(values))

    body = "".join(f"<tr>{cells('td', r)}</tr>" for r in rows)
    return (f'<div class="scroll"><table><thead><tr>{cells("th", head)}</tr></thead>'
            f"<tbody>{body}</tbody></table></div>")


def _metric_name(key: str) -> str:
    name = METRIC_NAMES.get(key)
    if name is None and key.startswith("ospa_"):
        suffix = {"_loc": " localisation", "_card": " cardinality"}
        base = key
        extra = ""
        for s, word in suffix.items():
            if key.endswith(s):
                base, extra = key[: -len(s)], word
        name = f"{_ospa_label(base)}{extra} (px)"
    return _e(name if name is not None else key)


#: columns of the summary tables per kind: (heading, metric key)
SUMMARY_COLUMNS = {
    "single": (("success AUC", "success_auc"), ("precision @ 20 px", "precision_at_20"),
               ("mean IoU", "mean_iou"), ("centre error (px)", "mean_centre_error")),
    "multi": (("MOTA", "mota"), ("IDF1", "idf1"), ("HOTA", "hota"),
              ("OSPA(50,1) px", "ospa_50_1"), ("|cardinality error|",
                                                "mean_abs_cardinality_error")),
    "unscored": (),
}
_KIND_TITLES = {"single": "Single-object runs", "multi": "Multi-target runs",
                "unscored": "Runs without ground truth"}


def _summary(groups: list[Group], stats: dict[tuple[str, str], dict[str, Stat]]) -> str:
    """One table per kind: a row per (sequence, model), its headline metrics."""
    out = []
    for kind, columns in SUMMARY_COLUMNS.items():
        gs = [g for g in groups if g.kind == kind]
        if not gs:
            continue
        rows = []
        for g in gs:
            st = stats[(g.sequence, g.label)]
            rows.append([_e(g.sequence), _e(g.label), str(len(g.runs))]
                        + [_fmt_stat(st[k]) if k in st else "–"
                           for k in ["run.frames"] + [k for _, k in columns] + ["fps"]])
        head = (["sequence", "model", "runs", "frames"] + [_e(h) for h, _ in columns]
                + ["frames/s"])
        out.append(f"<h3>{_KIND_TITLES[kind]}</h3>" + _table(head, rows, text_cols=2))
    return "".join(out)


def _draw_model(run: Run, images: _Images, label: str) -> tuple[str, bytes] | str:
    """The drawing of a run's ``model.json``: (file name, PNG bytes), or a note why not."""
    from pgm.core.graph import FactorGraph

    path = run.model_file
    if path is None:
        return "no model.json in the run folder"
    try:
        graph = FactorGraph.load(path)
    except (ValueError, KeyError, TypeError, AttributeError, IndexError,
            RecursionError) as exc:
        return f"{path} could not be loaded: {one_line(exc)[:200]}"
    out = images.path_for(f"graph-{label}")
    try:
        graph.draw(out)
    except (ValueError, KeyError, TypeError) as exc:
        return f"{path} could not be drawn: {one_line(exc)[:200]}"
    images.names.add(out.name)
    return out.name, out.read_bytes()


def _prepare_files(root: Path) -> Path:
    folder = root / FILES_DIR
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise InputError(f"{folder} exists and is not a folder; remove it to write the "
                         f"report")
    try:
        folder.mkdir(exist_ok=True)
        for old in folder.glob("*.png"):
            if old.is_file() or old.is_symlink():
                old.unlink()
    except OSError as exc:
        raise InputError(f"cannot write {folder}: {exc.strerror or one_line(exc)}") from None
    return folder


def _load_all(root: Path) -> tuple[list[Run], list[Run]]:
    folders = find_runs(root)
    if not folders:
        raise InputError(f"no runs under {root}: no folder holds a run.json or metrics.json "
                         f"(written by 'pgm track' or 'pgm bench')")
    runs = [load_run(f, root) for f in folders]
    done = [r for r in runs if r.complete]
    left = [r for r in runs if not r.complete]
    if not done:
        raise InputError(f"no finished run under {root}: {len(runs)} run folder(s), each "
                         f"with run.json saying \"complete\": false")
    return done, left


def write_report(root: str | Path, title: str | None = None) -> Path:
    """Write ``root/report.html`` (and ``root/report_files/*.png``) about every run
    under ``root``; returns the HTML path.

    Parameters
    ----------
    root : path
        A run folder or a folder of runs (any depth).
    title : str, optional
        The page's heading (default: ``Tracking report — <root's name>``).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        ``root`` missing or not a folder, no run found, no finished run, a corrupt
        ``run.json`` or ``metrics.json``, or a folder that cannot be written.
    """
    import pgm

    base = Path(root)
    runs, left = _load_all(base)
    _assign_labels(runs)
    splits = split_configurations(runs)
    for line in splits:
        _log.warning("report: %s", line)
    groups = _group(runs)
    stats = {(g.sequence, g.label): _group_stats(g) for g in groups}
    labels = sorted({g.label for g in groups})
    colours = _colours(labels)
    sequences = sorted({g.sequence for g in groups})
    images = _Images(_prepare_files(base))
    heading = title or f"Tracking report — {base.resolve().name or base}"
    parts: list[str] = []
    toc: list[tuple[str, str]] = [("summary", "Summary")]

    # -- summary
    parts.append('<section id="summary"><h2>Summary</h2>' + _summary(groups, stats)
                 + '<p class="note">Several runs of one sequence and model (seeds) are '
                   "averaged: mean ± standard deviation over the runs. Runs that differ in "
                   "length or settings are not seeds of one configuration: they are "
                   "separate rows, labelled with what differs.</p>"
                 + "".join(f'<p class="note warning">{_e(line)}.</p>' for line in splits)
                 + "</section>")

    # -- single object
    single = [g for g in groups if g.kind == "single"]
    if single:
        toc.append(("single-object", "Single-object tracking (OTB plots)"))
        out = ['<section id="single-object"><h2>Single-object tracking</h2>',
               '<p class="note">Success plot: fraction of scored frames whose IoU with the '
               "ground truth exceeds the threshold; the legend gives the success AUC (mean "
               "over the 21 thresholds 0, 0.05, …, 1; a perfect track scores 20/21 ≈ 0.952, "
               "the OTB convention). Precision plot: fraction of frames whose centre error "
               "is at most the distance; the legend gives the precision at 20 px. Shading: "
               "range over seeds.</p>"]
        per_label: dict[str, list[dict[str, Any]]] = {}
        seq_blocks = []
        for seq in sequences:
            entries = []
            for g in (g for g in single if g.sequence == seq):
                runs_ = g.scored()
                st = stats[(g.sequence, g.label)]
                e = {"label": g.label, "colour": colours[g.label],
                     "success": _mean_curve(runs_, "success"),
                     "precision": _mean_curve(runs_, "precision"),
                     "auc": st["success_auc"].mean if "success_auc" in st else None,
                     "p20": st["precision_at_20"].mean if "precision_at_20" in st else None,
                     "band": True}
                entries.append(e)
                per_label.setdefault(g.label, []).append(e)
            if entries:
                fig = _otb_figure(entries, seq)
                name, data = images.save_figure(fig, f"otb-{seq}")
                seq_blocks.append(f'<h3 id="otb-{_slug(seq)}">{_e(seq)}</h3>'
                                  + _img(name, data, f"success and precision plots, {seq}"))
        overall = []
        for label, es in sorted(per_label.items()):
            curves = {}
            for kind in ("success", "precision"):
                cs = [e[kind] for e in es if e[kind] is not None]
                curves[kind] = None if not cs else {
                    "x": cs[0]["x"], "y": np.mean([c["y"] for c in cs], axis=0),
                    "lo": None, "hi": None, "n": len(cs)}
            aucs = [e["auc"] for e in es if e["auc"] is not None]
            p20s = [e["p20"] for e in es if e["p20"] is not None]
            overall.append({"label": f"{label} ({len(es)} seq)", "colour": colours[label],
                            "success": curves["success"], "precision": curves["precision"],
                            "auc": float(np.mean(aucs)) if aucs else None,
                            "p20": float(np.mean(p20s)) if p20s else None, "band": False})
        fig = _otb_figure(overall, f"overall ({len({g.sequence for g in single})} "
                                   f"sequence(s))")
        name, data = images.save_figure(fig, "otb-overall")
        out.append('<h3 id="otb-overall">Overall</h3>'
                   + _img(name, data, "overall success and precision plots",
                          "Mean over sequences of each model's per-sequence curves; AUC "
                          "and precision in the legend are the means of the per-sequence "
                          "values."))
        out += seq_blocks
        out.append("</section>")
        parts.append("".join(out))

    # -- confidence calibration (single-object models that report a confidence)
    cal_entries = [(label, colours[label], cal) for label in labels
                   if (cal := _calibration([r for g in single if g.label == label
                                             for r in g.scored()])) is not None]
    if cal_entries:
        toc.append(("calibration", "Confidence calibration"))
        fig = _reliability_figure(cal_entries)
        name, data = images.save_figure(fig, "calibration")
        rows = [[_e(label), str(cal["sequences"]), str(cal["runs"]), str(cal["pooled"]["n"]),
                 _fmt3(cal["pooled"]["ece"]), _fmt3(cal["pooled"]["brier"]),
                 _fmt3(cal["pooled"]["mean_confidence"]), _fmt3(cal["pooled"]["hit_rate"]),
                 _fmt3(cal["mean_sequence_ece"])] for label, _, cal in cal_entries]
        parts.append(
            '<section id="calibration"><h2>Confidence calibration</h2>'
            '<p class="note">A model that writes a confidence per frame claims the '
            "probability that its box overlaps the truth by at least half (IoU ≥ 0.5). "
            "Frames are binned by confidence (10 bins) and each bin's hit rate is set "
            "against its mean confidence, pooled over the model's sequences with every "
            "sequence weighted equally (its seeds share its weight): what the confidence "
            "means on a frame of a sequence drawn at random. ECE: the weighted mean gap "
            "between confidence and hit rate; per sequence: the mean over sequences of "
            "each one's own ECE (a sequence can be over-confident where another is "
            "under-confident).</p>"
            + _img(name, data, "reliability diagram of the confidence")
            + _table(["model", "sequences", "runs", "frames", "ECE", "Brier",
                      "mean confidence", "hit rate", "ECE per sequence (mean)"], rows)
            + "</section>")

    # -- multi target
    multi = [g for g in groups if g.kind == "multi"]
    if multi:
        toc.append(("multi-target", "Multi-target tracking (MOT metrics, OSPA)"))
        out = ['<section id="multi-target"><h2>Multi-target tracking</h2>',
               '<p class="note">CLEAR MOT, identity and HOTA scores (higher is better; '
               "error bars: standard deviation over seeds) and mean set distances on box "
               "foot points (lower is better). Per-frame panels: OSPA between the ground "
               "truth and the estimate in each frame, and the number of targets (truth in "
               "black, each model's estimate in its colour), mean over seeds.</p>"]
        mseqs = [s for s in sequences if any(g.sequence == s for g in multi)]
        if len(mseqs) > 1:
            rows_ = []
            for label in labels:
                gs = [g for g in multi if g.label == label]
                if not gs:
                    continue
                keys = set().union(*(stats[(g.sequence, g.label)] for g in gs))
                mean_stats = {k: _stat([stats[(g.sequence, g.label)][k].mean
                                        for g in gs if k in stats[(g.sequence, g.label)]])
                              for k in keys}
                rows_.append((f"{label} ({len(gs)} seq)", colours[label], mean_stats))
            fig = _mot_figure(rows_, f"mean over {len(mseqs)} sequences")
            name, data = images.save_figure(fig, "mot-mean")
            out.append('<h3 id="mot-mean">Mean over sequences</h3>'
                       + _img(name, data, "MOT scores, mean over sequences",
                              "Unweighted mean of the per-sequence values; error bars: "
                              "standard deviation over sequences."))
        for seq in mseqs:
            gs = [g for g in multi if g.sequence == seq]
            fig = _mot_figure([(g.label, colours[g.label], stats[(g.sequence, g.label)])
                               for g in gs], seq)
            name, data = images.save_figure(fig, f"mot-{seq}")
            block = (f'<h3 id="mot-{_slug(seq)}">{_e(seq)}</h3>'
                     + _img(name, data, f"MOT scores, {seq}"))
            fig = _per_frame_figure(gs, colours, seq)
            if fig is None:
                block += ('<p class="note warn">No per-frame series in these runs\' '
                          "metrics.json (written before they were stored): run them again "
                          "to plot OSPA and cardinality per frame.</p>")
            else:
                name, data = images.save_figure(fig, f"ospa-{seq}")
                block += (f'<div id="ospa-{_slug(seq)}">'
                          + _img(name, data, f"per-frame OSPA and cardinality, {seq}")
                          + "</div>")
            out.append(block)
        out.append("</section>")
        parts.append("".join(out))

    # -- speed
    fps_rows = [(f"{g.sequence} · {g.label}", colours[g.label], stats[(g.sequence, g.label)]
                 ["fps"]) for g in groups if "fps" in stats[(g.sequence, g.label)]
                and stats[(g.sequence, g.label)]["fps"].mean is not None]
    if fps_rows:
        toc.append(("fps", "Frames per second"))
        fig = _fps_figure(fps_rows)
        name, data = images.save_figure(fig, "fps")
        parts.append('<section id="fps"><h2>Frames per second</h2>'
                     + _img(name, data, "frames per second per sequence and model",
                            "Inference only (engine steps): decoding, detection, drawing "
                            "and writing excluded; mean ± standard deviation over seeds.")
                     + "</section>")

    # -- models
    toc.append(("models", "Models (factor graphs)"))
    out = ['<section id="models"><h2>Models</h2><p class="note">The factor graph of each '
           "model as saved in its model.json: circles are variables, squares factors "
           "(coloured by kind), grey circles observations.</p><div class=\"graphs\">"]
    for label in labels:
        first = next(r for g in groups if g.label == label for r in g.runs)
        drawn = _draw_model(first, images, label)
        if isinstance(drawn, str):
            out.append(f'<figure><figcaption><b>{_e(label)}</b>: <span class="warn">'
                       f"{_e(drawn)}</span></figcaption></figure>")
        else:
            name, data = drawn
            out.append(_img(name, data, f"factor graph of {label}",
                            f"<b>{_e(label)}</b> — from {_e(first.rel)}/model.json"))
    out.append("</div></section>")
    parts.append("".join(out))

    # -- every scalar metric
    toc.append(("metrics", "Every scalar metric"))
    out = ['<section id="metrics"><h2>Every scalar metric</h2><p class="note">One table '
           "per sequence; each cell is the mean ± standard deviation over the model's runs "
           "(n in the heading); nested values (the confidence calibration) are dotted "
           "keys.</p>"]
    for seq in sequences:
        gs = [g for g in groups if g.sequence == seq]
        keys: list[str] = []
        for g in gs:
            keys += [k for k in stats[(g.sequence, g.label)] if k not in keys]
        head = ["metric", "key"] + [f"{_e(g.label)} (n={len(g.runs)})" for g in gs]
        rows = [[_metric_name(k), f"<code>{_e(k)}</code>"]
                + [_fmt_stat(stats[(g.sequence, g.label)][k])
                   if k in stats[(g.sequence, g.label)] else "–" for g in gs] for k in keys]
        out.append(f'<h3 id="metrics-{_slug(seq)}">{_e(seq)}</h3>'
                   + _table(head, rows, text_cols=2))
    out.append("</section>")
    parts.append("".join(out))

    # -- runs
    toc.append(("runs", "Runs"))
    rows = [[_e(r.rel), _e(r.sequence), _e(r.label), _e(r.kind),
             _fmt(r.info.get("frames") if _is_number(r.info.get("frames")) else None, True),
             _fmt(r.fps)] for g in groups for r in g.runs]
    out = ['<section id="runs"><h2>Runs</h2>',
           _table(["folder", "sequence", "model", "kind", "frames", "frames/s"], rows,
                  text_cols=4)]
    if left:
        out.append(f'<p class="note warn">Left out: {len(left)} unfinished run(s) '
                   f"(run.json says \"complete\": false).</p>")
        out.append(_table(["folder", "sequence", "model", "stopped"],
                          [[_e(r.rel), _e(r.sequence), _e(r.model),
                            _e(r.info.get("stopped", "–"))] for r in left], text_cols=4))
    out.append("</section>")
    parts.append("".join(out))

    nav = "".join(f'<li><a href="#{a}">{_e(t)}</a></li>' for a, t in toc)
    n_models = len(labels)
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_e(heading)}</title><style>{_CSS}</style></head><body><main>"
        f"<header><h1>{_e(heading)}</h1><p class=\"meta\">{len(runs)} run(s) of "
        f"{len(sequences)} sequence(s) and {n_models} model(s) under <code>{_e(base)}"
        f"</code>; pgm {_e(pgm.__version__)}.</p></header>"
        f'<nav id="contents"><h2>Contents</h2><ol>{nav}</ol></nav>'
        + "".join(parts)
        + '<footer>Written by <code>pgm report</code>. Images are embedded; the same PNGs '
          f"are in <code>{FILES_DIR}/</code> beside this page.</footer>"
          "</main></body></html>\n")
    path = base / REPORT_NAME
    write_text(path, page)
    return path


# --------------------------------------------------------------------------- CLI


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pgm report`` to the ``pgm`` sub-commands."""
    p = subparsers.add_parser(
        "report", help="write DIR/report.html about the runs under DIR",
        description="Write DIR/report.html, a self-contained page (images embedded, no "
                    "JavaScript) about\nevery run under DIR (a run folder written by "
                    "'pgm track', or a folder of runs at any depth,\ne.g. 'pgm bench' "
                    "output): OTB success/precision plots, MOT metric bars, per-frame "
                    "OSPA\nand cardinality, frames per second, each model's factor graph "
                    "and every scalar metric,\nseeds averaged. The PNGs are also written "
                    "to DIR/report_files/.",
        epilog="examples:\n  pgm track ../shared/data/TUD-Campus --model phd --out runs/tud "
               "--no-video\n  pgm report runs/tud\n  pgm report bench_out/   # every run "
               "under it")
    from pgm.app.cli import _path

    p.add_argument("dir", type=_path("DIR"), metavar="DIR",
                   help="a run folder or a folder of runs")
    p.add_argument("--title", default=None,
                   help="heading of the page (default: 'Tracking report — <DIR name>')")
    return p


def cmd_report(args) -> int:
    """``pgm report DIR``: write the report and say where."""
    path = write_report(args.dir, title=args.title)
    print(f"wrote {path} (images also in {path.parent / FILES_DIR})")
    return 0


COMMANDS = {"report": cmd_report}
