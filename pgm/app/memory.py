"""How much memory a run needs, estimated before it starts, and the cap it must fit under."""

from __future__ import annotations

import os
import re

import numpy as np

from pgm.core.errors import InputError
from pgm.core.graph import FactorGraph

__all__ = ["estimate_memory", "memory_limit", "check_memory", "MEMORY_BASE",
           "MEMORY_PER_PARTICLE_FACTOR", "MEMORY_PER_SET_PARTICLE", "MEMORY_PER_PIXEL_FACTOR",
           "DEFAULT_TARGETS"]

#: bytes of the interpreter, numpy, OpenCV and torch before any work (measured ~120 MB)
MEMORY_BASE = 200e6
#: bytes per particle of one variable, per factor that touches it (measured: 300-850 B
#: per particle and likelihood for the single-object models, x2 for safety)
MEMORY_PER_PARTICLE_FACTOR = 1024.0
#: bytes per particle of a ``set`` variable (PHD; measured ~70 B, x2)
MEMORY_PER_SET_PARTICLE = 160.0
#: bytes per frame pixel per appearance likelihood (integral histograms, colour bins,
#: gradient channels, FFTs of the frame cache)
MEMORY_PER_PIXEL_FACTOR = 64.0
#: targets assumed for a multi-target run whose detections are not known in advance
DEFAULT_TARGETS = 20


def estimate_memory(graph: FactorGraph, frame_size: tuple[int, int] | None, *,
                    num_particles: int | None = None, targets: int | None = None) -> float:
    """Bytes a run of ``graph`` needs, estimated before it starts.

    ``base + Σ_v N_v (k_v + 1) c + W H (L + 1) p``: for each variable ``v`` its particle
    count ``N_v`` (``num_particles``, else the graph's engine settings; per target ×
    ``targets`` for a ``set`` variable or a plate's), ``k_v`` the factors on it and ``c`` the bytes
    per particle and factor (:data:`MEMORY_PER_PARTICLE_FACTOR`,
    :data:`MEMORY_PER_SET_PARTICLE`); ``L`` the likelihood factors and ``p``
    :data:`MEMORY_PER_PIXEL_FACTOR` bytes per pixel of the ``(W, H)`` frame. The
    constants are twice the peak resident memory measured on the five models (50 to
    400 000 particles, 320×240 and 640×480 frames), so the estimate errs high.
    """
    settings = graph.meta.get("engine", {}) if isinstance(graph.meta, dict) else {}
    default = settings.get("num_particles", 100) if isinstance(settings, dict) else 100
    total = MEMORY_BASE
    n_lik = 0
    plated = graph.plate_variables
    for name, var in graph.variables.items():
        if num_particles is not None:
            n = num_particles
        elif isinstance(default, dict):
            n = default.get(name, 100)
        else:
            n = default
        facs = graph.factors_of(name)
        n_lik += sum(1 for f in facs if f.kind == "likelihood")
        if var.role == "set":
            n_targets = targets if targets is not None else DEFAULT_TARGETS
            total += float(n) * max(n_targets, 1) * (len(facs) + 1) * MEMORY_PER_SET_PARTICLE
        elif var.role in ("part", "latent") or var.dim > 0:
            k = max(targets if targets is not None else DEFAULT_TARGETS, 1) if name in plated \
                else 1
            total += float(n) * k * (len(facs) + 1) * MEMORY_PER_PARTICLE_FACTOR
    if frame_size is not None:
        total += float(frame_size[0]) * float(frame_size[1]) * (n_lik + 1) \
            * MEMORY_PER_PIXEL_FACTOR
    return total


_UNITS = {"": 1, "k": 1e3, "m": 1e6, "g": 1e9, "t": 1e12}


def _parse_bytes(text: str, what: str) -> float:
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:e[+-]?[0-9]+)?)\s*([kmgt]?)i?b?\s*", text.lower())
    if m is None or not np.isfinite(float(m.group(1))) or float(m.group(1)) <= 0:
        raise InputError(f"{what} must be a positive size such as 4G or 500M, got {text!r}")
    return float(m.group(1)) * _UNITS[m.group(2)]


def memory_limit() -> float:
    """The memory a run may use, in bytes: ``PGM_MEMORY_LIMIT`` (e.g. ``8G``) when set,
    else 80 % of the physical memory (``SC_PHYS_PAGES``; unlimited where it is not
    known). Not the memory free at the moment: a run is refused only when it cannot fit
    on the machine, never because another process is busy."""
    env = os.environ.get("PGM_MEMORY_LIMIT")
    if env:
        return _parse_bytes(env, "PGM_MEMORY_LIMIT")
    try:
        return 0.8 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (OSError, ValueError, AttributeError):
        return float("inf")


def check_memory(graph: FactorGraph, frame_size: tuple[int, int] | None, *,
                 num_particles: int | None = None, targets: int | None = None,
                 limit: float | None = None) -> float:
    """Raise :class:`InputError` when :func:`estimate_memory` exceeds ``limit`` (default
    :func:`memory_limit`), naming both; returns the estimate."""
    need = estimate_memory(graph, frame_size, num_particles=num_particles, targets=targets)
    cap = memory_limit() if limit is None else float(limit)
    if need > cap:
        size = f" and {frame_size[0]}x{frame_size[1]} frames" if frame_size else ""
        raise InputError(f"this run needs about {need / 1e9:.3g} GB ({graph.name!r} with its "
                         f"particle counts{size}) but the memory cap is {cap / 1e9:.3g} GB; "
                         f"use fewer --particles (the cap: --memory-limit, PGM_MEMORY_LIMIT or "
                         f"80% of the physical memory)")
    return need
