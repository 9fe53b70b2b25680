"""A discriminative, online-learned appearance factor: a correlation filter's response
map read by every particle.

A multi-channel linear correlation filter (MOSSE [#bolme2010] with the multi-channel
closed form of DSST [#danelljan2014]) is trained on a window around the object: it maps
the window's features to a Gaussian peak on the object's centre and low values on the
surrounding background, so it is *discriminative* (it learns what the object is not)
where a template or histogram only learns what it is. In each frame the filter is
applied to one search window per scale level with one FFT per channel; every particle
then reads the response at its own centre and scale (bilinear in position, linear in
log-scale between levels):

.. math::
    \\log p(z \\mid X) = \\lambda\\, \\frac{r(X)}{\\bar r}

where ``r̄`` is the running mean of the filter's own peak response at its estimates, so
the score is in units of "a typical peak on this video" whatever the object's texture.
The factor learns from the video as it runs (:meth:`CorrelationFilterLikelihood.update`):
after each frame, the window at the estimate is scored by the current filter first; the
filter is blended towards that window only when the score reaches ``gate · r̄`` (the
tracker's own confidence relative to its own history: an occluder or a drift does not
get learned), with ``adapt_rate`` as the learning rate.

After each frame the factor also records the **peak-to-sidelobe ratio** of the response
map at the estimate (MOSSE's failure signal [#bolme2010]: the peak's height above the
rest of the map, ``(max r − μ_side) / σ_side`` with the ``11 × 11`` cells around the
peak excluded — a tenth of the window's side at the default template size). It is a
ratio of the map to itself, so its meaning does not depend on the video's contrast or
texture; its logarithm is the feature the single-object model's confidence calibrates
(:attr:`CorrelationFilterLikelihood.confidence_feature`).

Features (per pixel of the window, resampled so the object is about ``target_px`` pixels
across): grey level and ``n_orient`` unsigned gradient-orientation channels (soft-binned
magnitudes, pooled over 3x3 and divided by the local gradient energy, so a global change
of illumination leaves them unchanged), all under a Hann window.

References
----------
.. [#bolme2010] D. S. Bolme, J. R. Beveridge, B. A. Draper and Y. M. Lui, "Visual object
   tracking using adaptive correlation filters", Proc. CVPR 2010, 2544–2550.
   doi:10.1109/CVPR.2010.5539960
.. [#danelljan2014] M. Danelljan, G. Häger, F. S. Khan and M. Felsberg, "Accurate scale
   estimation for robust visual tracking", Proc. BMVC 2014. doi:10.5244/C.28.65
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import scipy.fft as sfft

from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param

from .likelihoods import BoxAppearanceLikelihood, bounded_int, grey_frame

__all__ = ["CorrelationFilterLikelihood", "window_features", "peak_to_sidelobe"]

#: widest search window, in template pixels per side (``target_px · (1 + padding)``):
#: the window's features and spectra are ``(1 + n_orient) ·`` its area, per scale level
MAX_WINDOW_PX = 512


def peak_to_sidelobe(response: np.ndarray, radius: int) -> float:
    """Peak-to-sidelobe ratio of a response map [#bolme2010]: ``(max − μ) / σ`` of the
    cells outside the ``(2 radius + 1)²`` square around the peak (``σ`` floored at
    ``1e-12`` of the peak's magnitude, so a flat side lobe gives a large, finite ratio)."""
    r = np.asarray(response, dtype=float)
    iy, ix = np.unravel_index(int(np.argmax(r)), r.shape)
    side = np.ones(r.shape, dtype=bool)
    side[max(iy - radius, 0):iy + radius + 1, max(ix - radius, 0):ix + radius + 1] = False
    if not side.any():
        raise ValueError(f"the response map {r.shape} has no side lobe outside radius {radius}")
    lobe = r[side]
    peak = float(r[iy, ix])
    return float((peak - lobe.mean()) / max(float(lobe.std()), 1e-12 * max(abs(peak), 1e-300)))


def window_features(grey: np.ndarray, centre, size, out_shape, n_orient: int) -> np.ndarray:
    """Features ``(1 + n_orient, th, tw)`` of the window of ``size = (w, h)`` px centred
    on ``centre = (cx, cy)``, resampled to ``out_shape = (tw, th)`` (border replicated)."""
    tw, th = out_shape
    sx, sy = size[0] / tw, size[1] / th
    # pixel centre convention: output pixel (i + 0.5) maps to cx + (i + 0.5 - tw/2) * sx
    m = np.array([[sx, 0.0, centre[0] - sx * tw / 2 + 0.5 * sx - 0.5],
                  [0.0, sy, centre[1] - sy * th / 2 + 0.5 * sy - 0.5]])
    patch = cv2.warpAffine(grey, m, (tw, th), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                           borderMode=cv2.BORDER_REPLICATE)
    gx = cv2.Sobel(patch, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(patch, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.sqrt(gx * gx + gy * gy)
    theta = np.mod(np.arctan2(gy, gx), np.pi) * (n_orient / np.pi)  # [0, n_orient)
    feats = np.empty((1 + n_orient, th, tw), np.float32)
    energy = np.sqrt(np.maximum(cv2.boxFilter(mag * mag, -1, (5, 5)), 0)) + 1e-3 * 255
    for c in range(n_orient):  # soft (linear) binning on the circle of orientations
        d = np.abs(theta - c)
        d = np.minimum(d, n_orient - d)
        feats[1 + c] = cv2.boxFilter(mag * np.maximum(1 - d, 0), -1, (3, 3)) / energy
    mean, std = float(patch.mean()), float(patch.std()) + 1e-3 * 255
    feats[0] = (patch - mean) / std * 0.5  # grey, contrast-normalised
    return feats


class CorrelationFilterLikelihood(BoxAppearanceLikelihood):
    """Correlation-filter response as a particle likelihood (see the module docstring).

    Parameters
    ----------
    lam : float
        Sharpness: the log-likelihood of a particle on a typical peak is ``lam``.
    padding : float
        The search window is the box grown by ``padding`` of its size on every side in
        total (``1 + padding`` times the box); wider windows see faster motion.
    target_px : float
        The object's size (``sqrt(w h)``) in the resampled window, in pixels.
    n_orient : int
        Gradient-orientation channels.
    sigma : float
        Width of the Gaussian target peak, as a fraction of ``target_px``.
    reg : float
        Ridge regularisation of the filter (relative to the mean spectral energy).
    adapt_rate : float
        Learning rate of the filter (0: learned from the first frame only).
    gate : float
        Learn from a frame only when the filter's response at the estimate reaches
        ``gate`` times its running mean peak.
    scales : int
        Scale levels scored per frame (odd), ``scale_step`` apart, around the particles'
        mean scale.
    floor : float
        Response (in units of the typical peak) of a particle outside every window.
    """

    model_attr = "num"

    def __init__(self, variable: str, *, lam: float = 60.0, padding: float = 2.0,
                 target_px: float = 32.0, n_orient: int = 6, sigma: float = 0.1,
                 reg: float = 1e-2, adapt_rate: float = 0.02, gate: float = 0.5,
                 scales: int = 3, scale_step: float = 1.05, floor: float = -0.2,
                 box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, adapt_rate=adapt_rate,
                         name=name)
        n = self.name
        self.padding = float(check_finite_param(f"{n}.padding", padding, nonneg=True))
        self.target_px = float(check_finite_param(f"{n}.target_px", target_px, positive=True))
        self.sigma = float(check_finite_param(f"{n}.sigma", sigma, positive=True))
        self.reg = float(check_finite_param(f"{n}.reg", reg, positive=True))
        self.gate = float(check_finite_param(f"{n}.gate", gate, nonneg=True))
        self.scale_step = float(check_finite_param(f"{n}.scale_step", scale_step,
                                                   positive=True))
        self.floor = float(check_finite_param(f"{n}.floor", floor))
        self.n_orient = bounded_int(n, "n_orient", n_orient)
        self.scales = bounded_int(n, "scales", scales)
        if self.scales % 2 == 0:
            raise ValueError(f"factor {n!r}: scales must be a positive odd number")
        side = self.target_px * (1 + self.padding)
        if side > MAX_WINDOW_PX:
            raise ValueError(f"factor {n!r}: target_px {self.target_px:g} with padding "
                             f"{self.padding:g} makes a search window {side:.6g} px wide; "
                             f"at most {MAX_WINDOW_PX} (target_px · (1 + padding))")
        if self.scale_step <= 1.0 and self.scales > 1:
            raise ValueError(f"factor {n!r}: scale_step must exceed 1")
        self.num = None  # (C, th, tw) complex numerator  conj(G) · X_c
        self.den = None  # (th, tw) real denominator  Σ_c |X_c|²
        self.peak = None  # running mean of the peak response at the estimates
        self.last_response = None  # relative response at the last estimate
        self.last_psr = None  # peak-to-sidelobe ratio of the map at the last estimate

    @property
    def learns(self) -> bool:
        """Always: the estimate's response is scored after every frame (the confidence
        feature), and learned from when ``adapt_rate > 0``."""
        return True

    @property
    def confidence_feature(self) -> float | None:
        """``log`` of the peak-to-sidelobe ratio of the response map at the last estimate
        (None before the first update): what :func:`pgm.core.readout.confidence`
        calibrates."""
        if self.last_psr is None:
            return None
        return float(np.log(max(self.last_psr, 1e-3)))

    def params(self) -> dict[str, Any]:
        return {"lam": self.lam, "padding": self.padding, "target_px": self.target_px,
                "n_orient": self.n_orient, "sigma": self.sigma, "reg": self.reg,
                "adapt_rate": self.adapt_rate, "gate": self.gate, "scales": self.scales,
                "scale_step": self.scale_step, "floor": self.floor,
                "box_indices": list(self.box_indices)}

    # -- geometry ----------------------------------------------------------------------
    def _setup(self, box: np.ndarray) -> None:
        w, h = float(box[2]), float(box[3])
        k = self.target_px / np.sqrt(w * h)  # template px per image px
        tw = max(8, 2 * int(round(k * w * (1 + self.padding) / 2)))
        th = max(8, 2 * int(round(k * h * (1 + self.padding) / 2)))
        self.shape = (tw, th)
        self.ref_size = np.array([w, h]) * (1 + self.padding)  # window (px) at scale 1
        self.ref_scale = np.sqrt(w * h)
        hann = np.outer(np.hanning(th), np.hanning(tw)).astype(np.float32)
        self.hann = hann
        s = self.sigma * self.target_px
        yy, xx = np.mgrid[0:th, 0:tw]
        g = np.exp(-0.5 * (((xx - (tw - 1) / 2) ** 2 + (yy - (th - 1) / 2) ** 2) / s ** 2))
        self.gf = sfft.rfft2(g.astype(np.float32))

    def _spectrum(self, ctx: FrameContext, centre, scale: float) -> np.ndarray:
        feats = window_features(grey_frame(ctx), centre, self.ref_size * scale, self.shape,
                                self.n_orient)
        return sfft.rfft2(feats * self.hann, axes=(-2, -1))

    def _train(self, xf: np.ndarray, rate: float) -> None:
        num = np.conj(self.gf)[None] * xf
        den = np.sum((xf * np.conj(xf)).real, axis=0)
        if self.num is None:
            self.num, self.den = num, den
        else:
            self.num = (1 - rate) * self.num + rate * num
            self.den = (1 - rate) * self.den + rate * den

    def _response(self, zf: np.ndarray) -> np.ndarray:
        lam = self.reg * float(self.den.mean()) + 1e-12  # a flat window has no energy
        return sfft.irfft2(np.sum(np.conj(self.num) * zf, axis=0) / (self.den + lam),
                           s=self.hann.shape)

    @property
    def _psr_radius(self) -> int:
        """Half-side of the square around the peak left out of the side lobe: 5 cells at
        the default template size (MOSSE's 11 x 11)."""
        return max(2, int(round(0.15 * self.target_px)))

    # -- learning ----------------------------------------------------------------------
    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """Train the filter on the first frame's window at ``value``."""
        box = np.asarray(value, float)[list(self.box_indices)]
        if not (box[2] > 0 and box[3] > 0):
            raise ValueError(f"factor {self.name!r}: the initial box must have a positive "
                             f"size, got {box[2:].tolist()}")
        self._setup(box)
        self.num = None
        xf = self._spectrum(ctx, box[:2], np.sqrt(box[2] * box[3]) / self.ref_scale)
        self._train(xf, 1.0)
        response = self._response(xf)
        self.peak = max(float(response.max()), 1e-12)
        self.last_response = 1.0
        self.last_psr = peak_to_sidelobe(response, self._psr_radius)

    def update(self, estimates, scores, frame=None) -> None:
        """Score the estimate's window, then learn from it if the score passes the gate."""
        if frame is None or self.num is None:
            return
        box = np.asarray(estimates[self.variables[0]], float)[list(self.box_indices)]
        scale = np.sqrt(max(box[2] * box[3], 1e-12)) / self.ref_scale
        xf = self._spectrum(frame, box[:2], scale)
        response = self._response(xf)
        here = self._centre_max(response)
        self.last_response = here / self.peak
        self.last_psr = peak_to_sidelobe(response, self._psr_radius)
        if self.adapt_rate > 0 and here >= self.gate * self.peak:
            self._train(xf, self.adapt_rate)
            self.peak = (1 - self.adapt_rate) * self.peak + self.adapt_rate * here

    def _centre_max(self, r: np.ndarray) -> float:
        """The best response within a tenth of the target of the window centre (where the
        estimate sits; it is a particle mean, not the peak)."""
        th, tw = r.shape
        rad = max(1, int(round(0.1 * self.target_px)))
        cy, cx = (th - 1) / 2, (tw - 1) / 2
        y0, y1 = int(np.floor(cy)) - rad, int(np.ceil(cy)) + rad + 1
        x0, x1 = int(np.floor(cx)) - rad, int(np.ceil(cx)) + rad + 1
        return float(r[max(y0, 0):y1, max(x0, 0):x1].max())

    # -- scoring -----------------------------------------------------------------------
    def _maps(self, x: np.ndarray, ctx: FrameContext):
        """Response maps of this frame, one per scale level, around the particles' mean
        (computed at the first call in a frame and cached on it)."""
        def make():
            b = self.boxes(x)
            centre = b[:, :2].mean(axis=0)
            base = float(np.exp(np.mean(0.5 * np.log(np.maximum(b[:, 2] * b[:, 3],
                                                                 1e-12)))))
            base /= self.ref_scale
            k = np.arange(self.scales) - self.scales // 2
            levels = base * self.scale_step ** k
            maps = np.stack([self._response(self._spectrum(ctx, centre, s)) for s in levels])
            return centre, levels, maps / self.peak

        return ctx.cached(("cf-response", id(self)), make)

    def relative_response(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N,)`` response at each particle, in units of the typical peak."""
        self.require_model()
        centre, levels, maps = self._maps(x, ctx)
        b = self.boxes(x)
        n_lev, th, tw = maps.shape
        scale = np.sqrt(np.maximum(b[:, 2] * b[:, 3], 1e-12)) / self.ref_scale
        if n_lev > 1:
            pos = (np.log(scale) - np.log(levels[0])) / np.log(self.scale_step)
            pos = np.clip(pos, 0, n_lev - 1)
        else:
            pos = np.zeros(len(b))
        l0 = np.minimum(np.floor(pos).astype(np.intp), n_lev - 1)
        l1 = np.minimum(l0 + 1, n_lev - 1)
        fl = pos - l0
        out = np.zeros(len(b))
        for lev, wgt in ((l0, 1 - fl), (l1, fl)):
            # particle centre in the level's window: template px
            step = self.ref_size[None, :] * levels[lev][:, None] / np.array(self.shape)[None]
            u = (b[:, 0] - centre[0]) / step[:, 0] + (tw - 1) / 2
            v = (b[:, 1] - centre[1]) / step[:, 1] + (th - 1) / 2
            inside = (u >= 0) & (u <= tw - 1) & (v >= 0) & (v <= th - 1)
            u0 = np.clip(np.floor(u).astype(np.intp), 0, tw - 2)
            v0 = np.clip(np.floor(v).astype(np.intp), 0, th - 2)
            fu, fv = np.clip(u - u0, 0, 1), np.clip(v - v0, 0, 1)
            val = ((1 - fv) * ((1 - fu) * maps[lev, v0, u0] + fu * maps[lev, v0, u0 + 1])
                   + fv * ((1 - fu) * maps[lev, v0 + 1, u0] + fu * maps[lev, v0 + 1, u0 + 1]))
            out += wgt * np.where(inside, val, self.floor)
        return out

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return self.lam * self.relative_response(x, ctx)
