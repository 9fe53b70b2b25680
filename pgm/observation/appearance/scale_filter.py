"""A one-dimensional correlation filter over scale (DSST's scale filter [#danelljan2014]):
the object's size read by a filter *trained* to peak at the estimate's own size.

Reading the size from a position filter's response at a few window scales is biased:
the response falls off faster when the window grows (background comes in) than when it
shrinks, so its maximum sits a few per cent below the true size, and a filter that then
learns at that estimate carries the bias into the next frame — the size drifts down over
a long video (a constant-size synthetic object: 0.77 of its size after 1000 frames). This
factor learns the size instead. At the estimate it samples ``n_scales`` boxes of sizes
``scale_step ** n`` (``n = -(S-1)/2 … (S-1)/2``) times the estimate's, each resampled to
a fixed small patch (its grey level and gradient orientations,
:func:`~pgm.observation.appearance.correlation.patch_features`), and trains a filter that
maps that stack to a Gaussian over ``n`` centred on ``n = 0``; the filter is circular over
the scale axis, so it answers "how much larger or smaller than the estimate" by the same
rule at every size. Each particle reads the response of the frame's stack (taken at the
particles' mean box) at its own log-size, linearly between samples:

.. math::
    \\log p(z \\mid X) = \\lambda\\, \\frac{r(\\log s_X)}{\\bar r}

with ``r̄`` the running mean of the filter's own peak at its estimates (so the reading is
in units of a typical peak, as the position filter's). It reads only the size: pair it
with a position cue (``cf(scales=1)+scale`` in an ``appearance`` string).

References
----------
.. [#danelljan2014] M. Danelljan, G. Häger, F. S. Khan and M. Felsberg, "Accurate scale
   estimation for robust visual tracking", Proc. BMVC 2014. doi:10.5244/C.28.65
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import scipy.fft as sfft

from pgm.core.frame import FrameContext
from pgm.core.learned import LearnedState
from pgm.core.numerics import check_finite_param

from .base import BoxAppearanceLikelihood, bounded_int, grey_frame
from .correlation import filter_of, patch_features, ridge

__all__ = ["ScaleFilterLikelihood"]


@dataclass
class ScaleFilterState(LearnedState):
    """What :class:`ScaleFilterLikelihood` learns: the filter, its running peak and the
    size of its resampled patches."""

    num: np.ndarray | None = None  # (D, S) complex numerator  conj(G) · X_d
    den: np.ndarray | None = None  # (S,) real denominator  Σ_d |X_d|²
    peak: float | None = None
    shape: tuple[int, int] | None = None  # (pw, ph) of the resampled patches


class ScaleFilterLikelihood(BoxAppearanceLikelihood):
    """The object's log-size read by a learned 1-D scale filter (module docstring).

    Parameters
    ----------
    lam : float
        Sharpness: the log-likelihood of a particle at a typical peak's size.
    n_scales : int
        Scale samples per frame (odd).
    scale_step : float
        Ratio of neighbouring samples' sizes.
    patch_px : float
        Side (``sqrt(w h)``) of the resampled patch of each sample, pixels.
    n_orient : int
        Gradient-orientation channels of the patch features.
    sigma : float
        Width of the Gaussian label over the samples, in samples.
    reg : float
        Ridge regularisation (relative to the mean spectral energy).
    adapt_rate : float
        Learning rate (0: the first frame's filter kept).
    floor : float
        Reading (in units of the typical peak) of a particle beyond the sampled sizes.
    """

    model_attr = "num"
    State = ScaleFilterState

    def __init__(self, variable: str, *, lam: float = 60.0, n_scales: int = 17,
                 scale_step: float = 1.03, patch_px: float = 20.0, n_orient: int = 6,
                 sigma: float = 1.0, reg: float = 1e-2, adapt_rate: float = 0.02,
                 floor: float = -0.2, box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, adapt_rate=adapt_rate,
                         name=name)
        n = self.name
        self.n_scales = bounded_int(n, "n_scales", n_scales)
        if self.n_scales % 2 == 0 or self.n_scales < 3:
            raise ValueError(f"factor {n!r}: n_scales must be an odd number from 3, got "
                             f"{n_scales!r}")
        self.scale_step = float(check_finite_param(f"{n}.scale_step", scale_step,
                                                   positive=True))
        if self.scale_step <= 1.0:
            raise ValueError(f"factor {n!r}: scale_step must exceed 1, got {scale_step!r}")
        self.patch_px = float(check_finite_param(f"{n}.patch_px", patch_px, positive=True))
        self.n_orient = bounded_int(n, "n_orient", n_orient)
        self.sigma = float(check_finite_param(f"{n}.sigma", sigma, positive=True))
        self.reg = float(check_finite_param(f"{n}.reg", reg, positive=True))
        self.floor = float(check_finite_param(f"{n}.floor", floor))
        half = self.n_scales // 2
        self.offsets = np.arange(-half, half + 1, dtype=float)  # samples, log-size / log step
        # the label peaks at offset 0, which the circular FFT layout puts at index 0
        label = np.exp(-0.5 * (self.offsets / self.sigma) ** 2)
        self.gf = sfft.fft(np.fft.ifftshift(label))
        self.hann = np.hanning(self.n_scales + 2)[1:-1]  # no zero weight at the ends

    def params(self) -> dict[str, Any]:
        return {"lam": self.lam, "n_scales": self.n_scales, "scale_step": self.scale_step,
                "patch_px": self.patch_px, "n_orient": self.n_orient, "sigma": self.sigma,
                "reg": self.reg, "adapt_rate": self.adapt_rate, "floor": self.floor,
                "box_indices": list(self.box_indices)}

    # -- the stack of scale samples --------------------------------------------------
    def _stack(self, ctx: FrameContext, box: np.ndarray) -> np.ndarray:
        """Spectra ``(D, S)`` over the scale axis of the features of the ``S`` boxes
        centred on ``box`` with sizes ``box · scale_step ** offsets``."""
        grey = grey_frame(ctx)
        pw, ph = self.shape
        cx, cy, w, h = (float(v) for v in box)
        feats = np.empty((self.n_scales, (1 + self.n_orient) * pw * ph), np.float32)
        for k, f in enumerate(self.scale_step ** self.offsets):
            sx, sy = w * f / pw, h * f / ph
            m = np.array([[sx, 0.0, cx - 0.5 - sx * (pw / 2 - 0.5)],
                          [0.0, sy, cy - 0.5 - sy * (ph / 2 - 0.5)]])
            # area-averaged resampling: a sample larger than the patch is smoothed first
            # (no aliasing, so larger and smaller samples are read alike)
            step = max(sx, sy)
            src = grey if step <= 1.5 else self._blurred(ctx, int(2 * round(step / 2) + 1))
            patch = cv2.warpAffine(src, m, (pw, ph),
                                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                   borderMode=cv2.BORDER_REPLICATE)
            feats[k] = patch_features(patch, self.n_orient).ravel()
        feats *= self.hann[:, None].astype(np.float32)
        return sfft.fft(feats.T, axis=1)

    @staticmethod
    def _blurred(ctx: FrameContext, k: int) -> np.ndarray:
        """The frame's grey levels under a ``k x k`` box filter, once per frame and ``k``
        (the scoring and the learning stacks of a frame share them)."""
        return ctx.cached(("grey-f32-box", k), lambda: cv2.blur(grey_frame(ctx), (k, k)))

    def _response(self, zf: np.ndarray) -> np.ndarray:
        """The response ``(S,)`` of a stack, over the offsets (``-(S-1)/2 … (S-1)/2``)."""
        r = sfft.ifft(np.sum(np.conj(self.num) * zf, axis=0) / ridge(self.den, self.reg)).real
        return np.fft.fftshift(r)

    def _train(self, xf: np.ndarray, rate: float) -> None:
        num, den = filter_of(self.gf, xf)
        if self.num is None or rate >= 1.0:
            self.num, self.den = num, den
        else:
            self.num = (1 - rate) * self.num + rate * num
            self.den = (1 - rate) * self.den + rate * den

    # -- learning ----------------------------------------------------------------------
    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        box = np.asarray(value, float)[list(self.box_indices)]
        if not (box[2] > 0 and box[3] > 0):
            raise ValueError(f"factor {self.name!r}: the initial box must have a positive "
                             f"size, got {box[2:].tolist()}")
        k = self.patch_px / np.sqrt(box[2] * box[3])
        self.shape = (max(4, int(round(k * box[2]))), max(4, int(round(k * box[3]))))
        self.num = None
        xf = self._stack(ctx, box)
        self._train(xf, 1.0)
        self.peak = max(float(self._response(xf).max()), 1e-12)

    def update(self, estimates, scores, frame=None) -> None:
        """Learn from the stack at the estimate (the filter is trained to peak there)."""
        if frame is None or self.num is None or self.adapt_rate <= 0:
            return
        box = np.asarray(estimates[self.variables[0]], float)[list(self.box_indices)]
        xf = self._stack(frame, box)
        here = float(self._response(xf)[self.n_scales // 2])
        self._train(xf, self.adapt_rate)
        self.peak = (1 - self.adapt_rate) * self.peak + self.adapt_rate * max(here, 1e-12)

    # -- scoring -----------------------------------------------------------------------
    def relative_response(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N,)`` the response at each particle's log-size, in units of the typical
        peak; the stack is taken once per frame at the particles' mean box."""
        self.require_model()
        b = self.boxes(x)

        def make():
            mw, mh = np.exp(np.mean(np.log(np.maximum(b[:, 2:], 1e-12)), axis=0))
            box = np.array([*b[:, :2].mean(axis=0), mw, mh])
            return np.sqrt(mw * mh), self._response(self._stack(ctx, box)) / self.peak

        ref, resp = self._cached(ctx, ("scale-stack",), make)
        pos = (np.log(np.sqrt(np.maximum(b[:, 2] * b[:, 3], 1e-24)) / ref)
               / np.log(self.scale_step) + self.n_scales // 2)
        inside = (pos >= 0) & (pos <= self.n_scales - 1)
        p0 = np.clip(np.floor(pos).astype(np.intp), 0, self.n_scales - 2)
        f = np.clip(pos - p0, 0.0, 1.0)
        val = (1 - f) * resp[p0] + f * resp[p0 + 1]
        return np.where(inside, val, self.floor)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return self.lam * self.relative_response(x, ctx)
