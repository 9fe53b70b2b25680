"""The SORT family's constants in time: the Kalman noise of a
:class:`pgm.models.sort.Params` and its per-frame constants converted from a reference
frame rate to the video's (:func:`at_frame_rate`), and the lost-track buffer in frames
(:func:`lost_frames`). Kept apart from :mod:`pgm.models.sort`, which builds the graph
from what these return."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from pgm.core.numerics import check_finite_param

__all__ = ["at_frame_rate", "lost_frames", "noise_diagonals"]


def noise_diagonals(p) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Q, R, P0`` diagonals of ``p`` (a :class:`pgm.models.sort.Params`; the code's
    defaults where not given)."""
    if p.box_state == "xyxy":
        q, r, p0 = [0.01] * 8, [0.1] * 4, [1.0] * 8
    else:  # the trackers package's XCYCSR settings, i.e. the SORT paper's
        q, r, p0 = [1.0] * 4 + [0.01, 0.01, 0.0001], [1.0, 1.0, 10.0, 10.0], \
            [10.0] * 4 + [10000.0] * 3
    out = []
    for given, default, what in ((p.process_noise, q, "process_noise"),
                                 (p.measurement_noise, r, "measurement_noise"),
                                 (p.initial_cov, p0, "initial_cov")):
        v = np.asarray(default if given is None else given, dtype=float)
        if v.shape != (len(default),):
            raise ValueError(f"{what} needs {len(default)} values for the {p.box_state} state, "
                             f"got {v.size}")
        check_finite_param(what, v, positive=True)
        out.append(v)
    return out[0], out[1], out[2]


def at_frame_rate(p):
    """``p`` with its per-frame constants, given at ``p.reference_fps``, converted to the
    video's rate ``p.fps`` (``reference_fps`` None: ``p`` as it is).

    With ``τ = reference_fps / fps`` reference frames per video frame:

    * counts of frames (``min_hits``, ``recover_hits``, ``fill_after``, ``delta_t``) are
      windows of time: ``max(1, round(n / τ))`` — but with ``count_hits="detections"``
      the first three stay counts of detections;
    * the constant-velocity state's noise is a continuous-time random walk sampled every
      ``τ``: a box coordinate's process variance grows as ``τ``; a rate is per video
      frame, ``τ`` times the reference frame's, so its variance grows as ``τ³`` and its
      initial variance as ``τ²`` (the scale-aware stds: ``√τ``, ``τ^1.5`` and ``τ``) —
      with ``noise_per="detection"`` a step per detection instead: a coordinate's
      variance unchanged, a rate's (process and initial) as ``τ²``, its units only
      (stds: 1, ``τ`` and ``τ``) — and with ``noise_per="displacement"`` the step of a
      box's irregular displacement from one detection to the next: a coordinate's and a
      rate's process variance unchanged (a displacement of so many pixels changes the
      rate, in pixels per video frame, by as much at any rate), only the initial rate
      variance (an object's speed, per second) as ``τ²`` (stds: 1, 1 and ``τ``).

    The detector's noise ``R`` is per detection and does not change.

    >>> from pgm.models.sort import Params
    >>> q = at_frame_rate(replace(Params(), reference_fps=30.0, fps=10.0))
    >>> q.min_hits, q.process_noise[:4], q.process_noise[4:]
    (1, (0.03, 0.03, 0.03, 0.03), (0.27, 0.27, 0.27, 0.27))
    """
    if p.reference_fps is None:
        return p
    check_finite_param("reference_fps", p.reference_fps, positive=True)
    check_finite_param("fps", p.fps, positive=True)
    tau = float(p.reference_fps) / float(p.fps)
    q, _, p0 = noise_diagonals(p)
    n = 4  # the box's columns come first, their rates after them
    per_second = p.noise_per == "second"
    rate_power = {"second": 3, "detection": 2, "displacement": 0}[p.noise_per]
    q[:n] *= tau if per_second else 1.0
    q[n:] *= tau ** rate_power
    p0[n:] *= tau ** 2
    frames = lambda k: max(1, round(int(k) / tau))  # noqa: E731
    hits = frames if p.count_hits == "seconds" else int  # noqa: E731
    return replace(p, reference_fps=None, min_hits=hits(p.min_hits),
                   recover_hits=hits(p.recover_hits), delta_t=frames(p.delta_t),
                   fill_after=None if p.fill_after is None else hits(p.fill_after),
                   process_noise=tuple(float(v) for v in q),
                   initial_cov=tuple(float(v) for v in p0),
                   pos_std=p.pos_std * (math.sqrt(tau) if per_second else 1.0),
                   vel_std=p.vel_std * tau ** (rate_power / 2),
                   initial_pos_std=p.initial_pos_std or 2.0 * p.pos_std,
                   initial_rate_std=(p.initial_rate_std or 10.0 * p.vel_std) * tau)



def lost_frames(lost_buffer: int, fps: float) -> int:
    """Frames a confirmed track survives without a match: ``lost_buffer`` frames at 30
    frames/s at the video's rate (``max(1, ceil(fps / 30 · lost_buffer))``; 0 stays 0)."""
    if lost_buffer == 0:
        return 0
    return max(1, math.ceil(fps / 30.0 * lost_buffer))
