"""Argument checks shared by the synthetic-scene modules (one-line InputErrors)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pgm.core.errors import InputError


def _finite(name: str, values: Sequence[float], n: int | None = None) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a sequence of numbers, got {values!r}") from None
    if n is not None and len(out) != n:
        raise InputError(f"{name} must have {n} values, got {len(out)}")
    if not all(math.isfinite(v) for v in out):
        raise InputError(f"{name} must be finite, got {values!r}")
    return out


def _color(name: str, c: Sequence[float]) -> tuple[float, float, float]:
    out = _finite(name, c, 3)
    if not all(0.0 <= v <= 255.0 for v in out):
        raise InputError(f"{name} must be a BGR triple in [0, 255], got {c!r}")
    return out  # type: ignore[return-value]


def _box(name: str, box: Sequence[float]) -> tuple[float, float, float, float]:
    out = _finite(name, box, 4)
    if out[2] <= 0 or out[3] <= 0:
        raise InputError(f"{name} must have positive width and height, got {box!r}")
    return out  # type: ignore[return-value]


def _nonneg(name: str, v: float) -> float:
    v = float(v)
    if not math.isfinite(v) or v < 0:
        raise InputError(f"{name} must be a finite number >= 0, got {v!r}")
    return v


def _frame_range(start: int, end: int | None) -> tuple[int, int | None]:
    if isinstance(start, bool) or not isinstance(start, (int, np.integer)) or start < 1:
        raise InputError(f"start must be a 1-based frame number >= 1, got {start!r}")
    if end is not None:
        if isinstance(end, bool) or not isinstance(end, (int, np.integer)) or end <= start:
            raise InputError(f"end must be None or a frame number > start={start}, got {end!r}")
        end = int(end)
    return int(start), end


def _check_n_frames(n_frames: int) -> int:
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)):
        raise InputError(f"n_frames must be a positive integer, got {n_frames!r}")
    if n_frames <= 0:
        raise InputError(f"n_frames must be a positive integer, got {n_frames}")
    return int(n_frames)


