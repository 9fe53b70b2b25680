"""Re-detection of a lost target as a proposal of the engine.

When the tracker's calibrated confidence (:func:`pgm.core.readout.confidence`) falls
below ``below``, :class:`RedetectionProposal` scans the frame around the estimate with
an appearance cue that can (a correlation filter's :meth:`~pgm.observation.appearance.
correlation.CorrelationFilterLikelihood.detect`: its long-term filter over ``scan_side``
object sizes) and draws
a share ``fraction`` of the particles' positions near the highest peaks; the rest of each
particle (its size) and the other particles come from the transition. The engine
corrects every weight by ``p / ((1 - f) p + f q)``
(:class:`~pgm.factors.ProposalFactor`), so the posterior is the model's: the proposal
only puts particles where the model could not have sampled them. For that the
transition must give a far-away position some probability — the re-appearance of
:class:`~pgm.factors.AR2Transition` (``reappear_prob`` over the frame): a peak far from
the lost estimate is then taken when its likelihood outweighs the re-appearance's
prior odds, ``log(reappear_prob / area)`` against the density near the old position,
and not otherwise. The part graph leaves drawing the re-appearance to this proposal
(``AR2Transition(reappear_drawn=False)``), and the proposal tells the cue where it put
particles (``open_windows_at``), so that the cue reads those in windows of their own and
no others: a frame where no peak passes the proposal's tests is tracked as without it.

>>> from pgm.observation.appearance.redetection import RedetectionProposal
>>> RedetectionProposal("object", cue="cf").params()["below"]
0.5
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist
from typing import Any

import numpy as np

from pgm.core.boxes import mean_box_size
from pgm.core.frame import FrameContext
from pgm.core.learned import LearnedState
from pgm.core.numerics import check_finite_param, logsumexp
from pgm.factors.kinds import ProposalFactor

__all__ = ["RedetectionProposal"]


@dataclass
class RedetectionState(LearnedState):
    """What a :class:`RedetectionProposal` keeps between frames: the frames in a row with
    the confidence below ``below``, and this frame's peaks and spread."""

    _low: int = 0
    _centres: np.ndarray | None = None
    _std: float = 1.0


class RedetectionProposal(ProposalFactor):
    """Positions from the peaks of an appearance response around the estimate, when lost.

    Parameters
    ----------
    variable : str
        The object's box variable ``(cx, cy, w, h, ...)``.
    cue : str
        Name of the likelihood factor that scans the frame: it has
        ``detect(ctx, centre, scale, max_peaks) ->``
        :class:`~pgm.observation.appearance.correlation.Scan` and
        ``ref_scale`` (the first box's ``sqrt(w h)``), as the correlation filter does.
    fraction : float
        Share of the particles proposed in a frame where the proposal is on.
    below : float
        On when the previous frame's calibrated confidence is below this (always on
        where the graph declares no confidence) ...
    patience : int
        ... in ``patience`` frames in a row (1: the first such frame): a short dip of a
        drifting tracker is not a loss.
    peaks : int
        Peaks kept: at most this many, each at least half the best one's response.
    min_response : float, optional
        Keep only peaks whose response reaches this, in units of the long-term filter's
        typical peak (the cue's :meth:`detect` values). None (the default): the cue's own
        learning ``gate`` (0 for a cue without one), the response at which the filter
        takes a window for the object and learns from it: a place the memory would not
        learn from is not proposed either (Ma et al.'s re-detection threshold, in the
        filter's units). 0: no such test.
    false_alarm : float
        Keep only peaks the scan's own noise would reach with this probability per
        frame: a peak's standard score within the map must reach the upper
        ``false_alarm / M`` quantile of a standard normal, ``M`` the map's independent
        values (:class:`~pgm.observation.appearance.correlation.Scan`; a Bonferroni
        bound on the maximum of the map's noise). 1: no such test.
    spread : float
        Standard deviation of the proposed centres around a peak, in units of the
        object's size ``sqrt(w h)`` (0.1: the filter's own peak width).
    columns : (int, int)
        The position components.
    """

    State = RedetectionState

    def __init__(self, variable: str, *, cue: str, fraction: float = 0.5, below: float = 0.5,
                 patience: int = 1, peaks: int = 3, spread: float = 0.1,
                 false_alarm: float = 1e-3, min_response: float | None = None,
                 columns=(0, 1), name: str | None = None):
        super().__init__(variable, fraction=fraction, columns=columns, name=name)
        if not isinstance(cue, str) or not cue:
            raise ValueError(f"factor {self.name!r}: cue must name a likelihood factor")
        self.cue = cue
        self.below = float(check_finite_param(f"{self.name}.below", below, nonneg=True))
        if isinstance(peaks, bool) or int(peaks) != peaks or peaks < 1:
            raise ValueError(f"factor {self.name!r}: peaks must be a positive integer, got "
                             f"{peaks!r}")
        self.peaks = int(peaks)
        if isinstance(patience, bool) or int(patience) != patience or patience < 1:
            raise ValueError(f"factor {self.name!r}: patience must be a positive integer, got "
                             f"{patience!r}")
        self.patience = int(patience)
        self.spread = float(check_finite_param(f"{self.name}.spread", spread, positive=True))
        self.false_alarm = float(check_finite_param(f"{self.name}.false_alarm", false_alarm,
                                                    positive=True))
        if self.false_alarm > 1:
            raise ValueError(f"factor {self.name!r}: false_alarm must be in (0, 1], got "
                             f"{false_alarm!r}")
        if len(self.columns) != 2:
            raise ValueError(f"factor {self.name!r}: columns must be the two position "
                             f"components, got {list(self.columns)}")
        self.min_response = (None if min_response is None else float(
            check_finite_param(f"{self.name}.min_response", min_response, nonneg=True)))

    def params(self) -> dict[str, Any]:
        return {"cue": self.cue, "fraction": self.fraction, "below": self.below,
                "patience": self.patience, "peaks": self.peaks, "spread": self.spread,
                "false_alarm": self.false_alarm, "min_response": self.min_response,
                "columns": list(self.columns)}

    def prepare(self, ctx: FrameContext, past, *, confidence, factors) -> float:
        """Off (0) while the confidence is at least ``below``; else the frame's peaks
        around the particles' mean size, and ``fraction`` (0 where no peak passes the
        tests: positive, at least half the best, ``min_response``, ``false_alarm``)."""
        if confidence is not None and confidence >= self.below:
            self._low = 0
            return 0.0
        self._low += 1
        if self._low < self.patience:
            return 0.0
        cue = factors.get(self.cue)
        if cue is None or not hasattr(cue, "detect"):
            raise ValueError(f"factor {self.name!r}: cue {self.cue!r} is not a factor of this "
                             f"graph that can scan a frame (detect())")
        b = cue.boxes(past[0])
        size = mean_box_size(b)
        centre = b[:, :2].mean(axis=0)
        scan = cue.detect(ctx, centre, size / cue.ref_scale, self.peaks)
        vals = scan.values
        floor = getattr(cue, "gate", 0.0) if self.min_response is None else self.min_response
        keep = (vals > 0) & (vals >= 0.5 * (vals.max() if vals.size else 0)) & (vals >= floor)
        if self.false_alarm < 1:  # above what the noise of the map's maximum reaches
            tail = min(self.false_alarm / max(scan.independent, 1.0), 0.5)
            keep &= scan.z >= -NormalDist().inv_cdf(tail)  # the upper tail's quantile
        if not keep.any():
            return 0.0
        self._centres = scan.centres[keep]
        self._std = self.spread * size
        if hasattr(cue, "open_windows_at"):  # the cue reads the proposed particles there
            cue.open_windows_at(ctx, self._centres)
        return self.fraction

    def sample(self, rng: np.random.Generator, ctx: FrameContext, *past: np.ndarray
               ) -> np.ndarray:
        if self._centres is None:
            raise ValueError(f"factor {self.name!r}: sample() before prepare() found peaks")
        x = np.array(past[0], dtype=float)
        pick = rng.integers(len(self._centres), size=x.shape[0])
        x[:, list(self.columns)] = (self._centres[pick]
                                    + self._std * rng.standard_normal((x.shape[0], 2)))
        return x

    def log_prob(self, x: np.ndarray, ctx: FrameContext, *past: np.ndarray) -> np.ndarray:
        """``log (1/m) Σ_k N(x_pos; peak_k, spread² I)`` of the position components."""
        d = (x[:, None, list(self.columns)] - self._centres[None]) / self._std
        log_k = -0.5 * np.sum(d * d, axis=2) - 2 * np.log(self._std) - np.log(2 * np.pi)
        return logsumexp(log_k, axis=1) - np.log(len(self._centres))
