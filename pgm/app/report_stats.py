"""``pgm report``: the numbers of the runs (:mod:`pgm.app.report`): each run's scalar
metrics, their mean and standard deviation over seeds (:class:`Stat`), how a number is
printed, and the mean success/precision curves and per-frame series over runs."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.app.report_runs import Group, Run, _is_number, _numbers
from pgm.core.errors import InputError


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
