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

With ``context_rate > 0`` (an option: the default single-object tracker leaves it at 0)
the factor also learns, from the object's motion, which cells of its window move with the object and
weights the filter by that probability, so that a static, textured background the
object moves over stops holding the response; on a moving camera it is dropped
(``CorrelationFilterLikelihood``, ``context_rate``).

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
.. [#ma2015] C. Ma, X. Yang, C. Zhang and M.-H. Yang, "Long-term correlation tracking",
   Proc. CVPR 2015, 5388–5396. doi:10.1109/CVPR.2015.7299177
"""

from __future__ import annotations

from typing import Any, NamedTuple

import cv2
import numpy as np
import scipy.fft as sfft

from pgm.core.boxes import mean_box_size
from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param
from pgm.observation.camera_motion import CameraMotionEstimator

from .likelihoods import BoxAppearanceLikelihood, bounded_int, grey_frame

__all__ = ["CorrelationFilterLikelihood", "window_features", "patch_features",
           "peak_to_sidelobe", "response_peaks", "Scan", "filter_of", "ridge"]

#: widest search window, in template pixels per side (``target_px · (1 + padding)``):
#: the window's features and spectra are ``(1 + n_orient) ·`` its area, per scale level
MAX_WINDOW_PX = 512
#: frames are checked for a still camera (while the context is learned) at most this
#: many pixels wide: the verdicts on the shared sequences are those at 640
CAMERA_CHECK_PX = 320


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


#: widest region scanned for re-detection (:meth:`CorrelationFilterLikelihood.detect`), in
#: template pixels per side: a larger frame is scanned in a window of this side around
#: the last estimate
MAX_DETECT_PX = 1024
#: windows a frame's particles may open (:meth:`CorrelationFilterLikelihood.relative_response`):
#: the first at the particles' mean, the others at particles outside every window so far
MAX_WINDOWS = 4


class Scan(NamedTuple):
    """A whole-frame scan (:meth:`CorrelationFilterLikelihood.detect`)."""

    centres: np.ndarray  #: (m, 2) peak centres, image pixels
    values: np.ndarray  #: (m,) relative responses
    z: np.ndarray  #: (m,) standard scores within the scanned map
    independent: float  #: independent values in the map (for a max-of-noise threshold)


def response_peaks(response: np.ndarray, radius: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` highest local maxima of a map, at least ``radius`` cells apart (a
    maximum of its ``(2 radius + 1)²`` neighbourhood): rows and columns ``(m, 2)`` as
    ``(x, y)``, and their values ``(m,)``, highest first (``m <= k``)."""
    r = np.asarray(response, dtype=np.float32)
    size = 2 * int(radius) + 1
    dil = cv2.dilate(r, np.ones((size, size), np.uint8))
    ys, xs = np.nonzero(r >= dil)
    vals = r[ys, xs]
    order = np.argsort(-vals, kind="stable")
    keep: list[int] = []
    for i in order:  # suppress plateaus: one maximum per neighbourhood
        if all(max(abs(xs[i] - xs[j]), abs(ys[i] - ys[j])) > radius for j in keep):
            keep.append(int(i))
            if len(keep) == k:
                break
    idx = np.array(keep, dtype=np.intp)
    return np.stack([xs[idx], ys[idx]], axis=1).astype(float), vals[idx].astype(float)


def filter_of(gf: np.ndarray, xf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The filter ``(num, den)`` that one sample of spectrum ``xf`` ``(C, ...)`` alone
    gives for the label spectrum ``gf`` (MOSSE / DSST's closed form, any dimension):
    ``conj(G) · X_c`` and ``Σ_c |X_c|²``."""
    return np.conj(gf)[None] * xf, np.sum((xf * np.conj(xf)).real, axis=0)


def ridge(den: np.ndarray, reg: float) -> np.ndarray:
    """A filter's denominator plus its ridge: ``reg`` times its mean energy (and a floor,
    since a flat window has none)."""
    return den + (reg * float(den.mean()) + 1e-12)


def _one_cloud(xy: np.ndarray, centre: np.ndarray, quarter: np.ndarray) -> bool:
    """Whether nine in ten points lie within ``quarter`` (per axis) of ``centre``."""
    return bool(np.mean(np.all(np.abs(xy - centre) <= quarter, axis=1)) >= 0.9)


def window_features(grey: np.ndarray, centre, size, out_shape, n_orient: int,
                    angle: float = 0.0) -> np.ndarray:
    """Features ``(1 + n_orient, th, tw)`` of the window of ``size = (w, h)`` px centred
    on ``centre = (cx, cy)`` and turned by ``angle`` (radians, image axes: x right, y
    down), resampled to ``out_shape = (tw, th)`` (border replicated)."""
    tw, th = out_shape
    sx, sy = size[0] / tw, size[1] / th
    c, s = np.cos(angle), np.sin(angle)
    # pixel centre convention: output pixel (i, j) maps to
    # centre - 0.5 + R(angle) diag(sx, sy) (i + 0.5 - tw/2, j + 0.5 - th/2)
    a0, b0 = 0.5 - tw / 2, 0.5 - th / 2
    m = np.array([[c * sx, -s * sy, centre[0] - 0.5 + c * sx * a0 - s * sy * b0],
                  [s * sx, c * sy, centre[1] - 0.5 + s * sx * a0 + c * sy * b0]])
    patch = cv2.warpAffine(grey, m, (tw, th), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                           borderMode=cv2.BORDER_REPLICATE)
    return patch_features(patch, n_orient)


def patch_features(patch: np.ndarray, n_orient: int) -> np.ndarray:
    """Features ``(1 + n_orient, h, w)`` of a grey ``float32`` patch: its grey level
    (contrast-normalised) and ``n_orient`` locally normalised gradient orientations."""
    th, tw = patch.shape
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
    memory_rate : float
        Learning rate of the *long-term* filter (a memory of the confident frames, after
        Ma et al. [#ma2015]): learned from the first frame and then from the same gated
        frames as the filter, ``memory_rate`` at a time (0: the first frame's filter
        kept). :meth:`detect` scans the frame with it: a target the short-term filter
        drifted away from is still recognised.
    context_rate : float
        Learn which cells of the window move with the object (0, the default: none,
        every cell counts; ``docs/results.md`` measures 0.05 and 0.2). The filter is trained on a
        window three times the object's size, so on a static, textured background the
        learned background can hold the response where the window sits while the object
        moves away. With ``context_rate > 0`` each cell carries the probability that it
        moves with the object (:attr:`context`: the box's cells 1, the others starting
        at even odds) and the filter is weighted cell by cell by it. After each learned
        frame the last learned window is compared with this frame at the object's new
        place and at the window's old place: the squared feature differences of the two
        (pooled 3 x 3, over their window's typical one) give each cell's log-odds
        (clipped at ±4), blended in at ``context_rate``. Where the estimate moved less
        than a cell (a tracker held by the background does not move), the window is
        compared instead at the place the filter's box cells alone put the object (their
        response's peak; the object is taken to have been at the last window's centre).
        A frame is used only when the box's own cells bear the move out (their mean
        log-odds is positive) and their response at the estimate passes the ``gate`` of
        their own running peak (the whole window's response stays high while it rests on
        learned background, the box's alone does not). The comparison needs a still
        camera: the frames are checked for camera motion
        (:class:`~pgm.observation.camera_motion.CameraMotionEstimator` at most
        :data:`CAMERA_CHECK_PX` wide: each of the first 20 frames on its own, a corner
        moved by a pixel being enough; then ``auto``'s verdict, 16 of the last 20
        frames), and once the camera is found moving the context is dropped for good
        (:attr:`camera_moved_at`; every cell counts again, as with ``context_rate=0``).
    angle_index : int, optional
        The state's in-plane rotation component (radians; None: no rotation, the
        default). The filter then learns the window turned by the estimate's angle (it
        stays in the object's own frame), and each frame adds two maps at the particles'
        mean angle ``± angle_step`` at their mean scale; a particle reads the scale maps
        at the mean angle plus the change the angle maps give at its own angle (a
        first-order, separable reading of the scale × angle grid).
    angle_step : float
        Spacing of the angle maps (radians).
    windows : int
        Search windows a frame's particles may open (:meth:`relative_response`): 1 (the
        default), one window at the particles' mean, a particle outside it scores
        ``floor``; more (at most :data:`MAX_WINDOWS`; re-detection sets it) when a
        proposal puts particles far from the others.
    """

    model_attr = "num"

    def __init__(self, variable: str, *, lam: float = 60.0, padding: float = 2.0,
                 target_px: float = 32.0, n_orient: int = 6, sigma: float = 0.1,
                 reg: float = 1e-2, adapt_rate: float = 0.02, gate: float = 0.5,
                 scales: int = 3, scale_step: float = 1.05, floor: float = -0.2,
                 memory_rate: float = 0.002, context_rate: float = 0.0, windows: int = 1,
                 angle_index: int | None = None,
                 angle_step: float = 0.1, box_indices=(0, 1, 2, 3), name: str | None = None):
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
        self.memory_rate = float(check_finite_param(f"{n}.memory_rate", memory_rate,
                                                    nonneg=True))
        if self.memory_rate > 1:
            raise ValueError(f"factor {n!r}: memory_rate must be in [0, 1], got {memory_rate}")
        self.context_rate = float(check_finite_param(f"{n}.context_rate", context_rate,
                                                     nonneg=True))
        if self.context_rate > 1:
            raise ValueError(f"factor {n!r}: context_rate must be in [0, 1], got "
                             f"{context_rate}")
        self.n_orient = bounded_int(n, "n_orient", n_orient)
        self.windows = bounded_int(n, "windows", windows)  # at most MAX_WINDOWS
        if angle_index is not None and (isinstance(angle_index, bool)
                                        or int(angle_index) != angle_index or angle_index < 0):
            raise ValueError(f"factor {n!r}: angle_index must be a component index, got "
                             f"{angle_index!r}")
        self.angle_index = None if angle_index is None else int(angle_index)
        self.angle_step = float(check_finite_param(f"{n}.angle_step", angle_step,
                                                   positive=True))
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
        self.memory = None  # the long-term filter: (num, den, peak)
        self.context = None  # (th, tw) probability that a cell moves with the object
        self.object_peak = None  # running mean peak of the filter's box cells alone
        self.camera_moved_at = None  # the frame where the camera was found moving
        self._first_frames = None  # the check of each of the first frames (see update)
        self._checked = 0  # frames it checked: the context weights the filter from one on
        self._checked_index = None  # the last frame checked
        self._camera = None  # the still-camera check while the context is learned
        self._mask_cache = None
        self._last_seen = None  # (features, centre, scale, angle) of the last learned frame

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
                "memory_rate": self.memory_rate, "context_rate": self.context_rate,
                "windows": self.windows,
                "angle_index": self.angle_index, "angle_step": self.angle_step,
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
        # the cells over the object's box (the rest is context)
        ih = np.abs(np.arange(th) - (th - 1) / 2) <= th / (1 + self.padding) / 2
        iw = np.abs(np.arange(tw) - (tw - 1) / 2) <= tw / (1 + self.padding) / 2
        self.box_cells = ih[:, None] & iw[None, :]
        s = self.sigma * self.target_px
        yy, xx = np.mgrid[0:th, 0:tw]
        g = np.exp(-0.5 * (((xx - (tw - 1) / 2) ** 2 + (yy - (th - 1) / 2) ** 2) / s ** 2))
        self.gf = sfft.rfft2(g.astype(np.float32))

    def _angle(self, value: np.ndarray) -> float:
        """The in-plane angle of a state (0 without an angle component)."""
        return 0.0 if self.angle_index is None else float(value[self.angle_index])

    def _features(self, ctx: FrameContext, centre, scale: float,
                  angle: float = 0.0) -> np.ndarray:
        return window_features(grey_frame(ctx), centre, self.ref_size * scale, self.shape,
                               self.n_orient, angle)

    def _spectrum(self, ctx: FrameContext, centre, scale: float,
                  angle: float = 0.0, feats: np.ndarray | None = None) -> np.ndarray:
        if feats is None:
            feats = self._features(ctx, centre, scale, angle)
        return sfft.rfft2(feats * self.hann, axes=(-2, -1))

    def _filter_of(self, xf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The filter ``(num, den)`` that one window of spectrum ``xf`` alone gives."""
        return filter_of(self.gf, xf)

    def _regularised(self, den: np.ndarray) -> np.ndarray:
        """The filter's denominator plus its ridge ``λ``."""
        return ridge(den, self.reg)

    def _train(self, xf: np.ndarray, rate: float) -> None:
        self._mask_cache = None
        num, den = self._filter_of(xf)
        if self.num is None:
            self.num, self.den = num, den
        else:
            self.num = (1 - rate) * self.num + rate * num
            self.den = (1 - rate) * self.den + rate * den

    def _response(self, zf: np.ndarray, num=None, den=None) -> np.ndarray:
        """The response map of the window with spectrum ``zf`` (of the short-term filter,
        or of the filter ``num, den``)."""
        if num is None and den is None and self.context is not None and self._checked:
            return sfft.irfft2(np.sum(self._masked_filter() * zf, axis=0), s=self.hann.shape)
        num = self.num if num is None else num
        den = self.den if den is None else den
        return sfft.irfft2(np.sum(np.conj(num) * zf, axis=0) / self._regularised(den),
                           s=self.hann.shape)

    def _masked_filter(self) -> np.ndarray:
        """The short-term filter's spectrum with each cell weighted by the probability
        that it moves with the object (:attr:`context`), cached until either changes."""
        if self._mask_cache is None:
            self._mask_cache = self._weighted_filter(self.context)
        return self._mask_cache

    def _weighted_filter(self, weights: np.ndarray) -> np.ndarray:
        """The short-term filter's spectrum with its cell ``(i, j)`` of the window
        weighted by ``weights[i, j]``."""
        th, tw = self.hann.shape
        h = sfft.irfft2(np.conj(self.num) / self._regularised(self.den), s=(th, tw))
        # the filter's cell (0, 0) is the window centre's: the weights are centred likewise
        return sfft.rfft2(h * np.fft.ifftshift(weights), axes=(-2, -1))

    def _learn_memory(self, xf: np.ndarray, here: float | None) -> None:
        """The long-term filter: the first frame's, then blended at ``memory_rate``."""
        num, den = self._filter_of(xf)
        if self.memory is None or here is None:
            resp = self._response(xf, num, den)
            self.memory = (num, den, max(float(resp.max()), 1e-12))
            return
        if self.memory_rate == 0:
            return
        r = self.memory_rate
        m_num, m_den, m_peak = self.memory
        here_lt = self._centre_max(self._response(xf, m_num, m_den))
        self.memory = ((1 - r) * m_num + r * num, (1 - r) * m_den + r * den,
                       (1 - r) * m_peak + r * here_lt)

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
        scale = np.sqrt(box[2] * box[3]) / self.ref_scale
        angle = self._angle(np.asarray(value, float))
        feats = self._features(ctx, box[:2], scale, angle)
        xf = self._spectrum(ctx, box[:2], scale, angle, feats)
        # the box is the object's; whether the rest of the window moves with it is not
        # known yet: even odds
        self.context = (np.where(self.box_cells, 1.0, 0.5) if self.context_rate > 0
                        else None)
        self._last_seen = (feats, box[:2].copy(), scale, angle)
        self.camera_moved_at = None
        self._camera = self._first_frames = None
        if self.context is not None:
            self._camera = CameraMotionEstimator("auto", max_side=CAMERA_CHECK_PX)
            self._first_frames = CameraMotionEstimator("on", max_side=CAMERA_CHECK_PX)
            self._checked = 0
            for check in (self._camera, self._first_frames):
                check(ctx.image)
            self._checked_index = ctx.index
        self._train(xf, 1.0)
        response = self._response(xf)
        self.peak = max(float(response.max()), 1e-12)
        self.last_response = 1.0
        self.last_psr = peak_to_sidelobe(response, self._psr_radius)
        self.memory = None
        self._learn_memory(xf, None)
        self.object_peak = (self._centre_max(self._object_response(xf))
                            if self.context is not None else None)

    def update(self, estimates, scores, frame=None) -> None:
        """Score the estimate's window, then learn from it if the score passes the gate."""
        if frame is None or self.num is None:
            return
        self._check_camera(frame)
        est = np.asarray(estimates[self.variables[0]], float)
        box = est[list(self.box_indices)]
        scale = np.sqrt(max(box[2] * box[3], 1e-12)) / self.ref_scale
        angle = self._angle(est)
        feats = self._features(frame, box[:2], scale, angle)
        xf = self._spectrum(frame, box[:2], scale, angle, feats)
        response = self._response(xf)
        here = self._centre_max(response)
        self.last_response = here / self.peak
        self.last_psr = peak_to_sidelobe(response, self._psr_radius)
        if here < self.gate * self.peak:
            return
        if self.context is not None:
            # the box's own cells must pass the gate too: the full window's response
            # stays high while the filter rests on a static context it has learned
            obj = self._object_response(xf)
            here_obj = self._centre_max(obj)
            if here_obj < self.gate * self.object_peak:
                return
            self.object_peak = ((1 - self.adapt_rate) * self.object_peak
                                + self.adapt_rate * here_obj)
            self._learn_context(frame, feats, box[:2], scale, angle, obj)
        if self.adapt_rate > 0:
            self._train(xf, self.adapt_rate)
            self.peak = (1 - self.adapt_rate) * self.peak + self.adapt_rate * here
        self._learn_memory(xf, here)

    def _check_camera(self, frame: FrameContext) -> None:
        """Once per frame, before the frame's response is read (and at the latest in
        :meth:`update`): on a moving camera the background moves in the image, and "did
        this cell stay where it was?" no longer tells it from the object, so the context
        is dropped for good."""
        if (self._camera is not None and frame.index != self._checked_index
                and self._camera_moved(frame)):
            self.context = self._camera = self._first_frames = self._mask_cache = None
            self.camera_moved_at = frame.index

    def _camera_moved(self, frame: FrameContext) -> bool:
        """Is the camera moving? The still-camera check's verdict (``auto``: 16 of the
        last 20 frames moved by a pixel or more); until it can have one (the first 20
        frames), each frame is checked on its own and one that moved is enough."""
        self._checked_index = frame.index
        image = frame.image
        if self._camera(image) is not None:
            return True
        if self._first_frames is None:
            return False
        w, h = image.shape[1], image.shape[0]
        a = self._first_frames(image)
        self._checked += 1
        if self._checked >= self._camera.window:
            self._first_frames = None
        return a is not None and self._camera.corner_shift(a, w, h) >= self._camera.min_shift

    def _learn_context(self, frame: FrameContext, feats: np.ndarray, centre, scale: float,
                       angle: float, obj: np.ndarray) -> None:
        """Which cells of the window move with the object (the class docstring,
        ``context_rate``): compared with the last learned frame's window, does a cell's
        content now sit at the object's new place or where the window was? ``obj`` is
        this frame's response of the filter's box cells alone at the estimate, whose
        peak places the object when the estimate did not move."""
        seen, c0, s0, a0 = self._last_seen
        step = self.ref_size * s0 / np.array(self.shape, float)  # image px per cell
        here = np.asarray(centre, float)
        if np.hypot(*((here - c0) / step)) >= 1.0:
            new = feats  # the estimate followed the object
        else:  # the estimate stayed: the box's own cells place the object in the window
            th, tw = obj.shape
            iy, ix = np.unravel_index(int(np.argmax(obj)), obj.shape)
            d = np.array([ix - (tw - 1) / 2, iy - (th - 1) / 2]) + (here - c0) / step
            if np.hypot(*d) < 1.0:
                return  # no move seen: the two places cannot be told apart
            c, s = np.cos(a0), np.sin(a0)
            off = np.array([c * d[0] * step[0] - s * d[1] * step[1],
                            s * d[0] * step[0] + c * d[1] * step[1]])
            new = self._features(frame, c0 + off, s0, a0)
        still = self._features(frame, c0, s0, a0)  # this frame where the window was
        moved = cv2.boxFilter(np.sum((new - seen) ** 2, axis=0), -1, (3, 3))
        stayed = cv2.boxFilter(np.sum((still - seen) ** 2, axis=0), -1, (3, 3))
        typical = float(np.median(np.minimum(moved, stayed))) + 1e-12
        odds = np.clip((stayed - moved) / typical, -4.0, 4.0)
        if float(odds[self.box_cells].mean()) <= 0.0:
            return  # the box's own content does not bear the move out
        r = self.context_rate
        self.context = (1 - r) * self.context + r / (1.0 + np.exp(-odds))
        self.context[self.box_cells] = 1.0  # the box is the object's, by definition
        self._mask_cache = None
        self._last_seen = (feats, here.copy(), scale, angle)

    def _object_response(self, xf: np.ndarray) -> np.ndarray:
        """The response map of the filter's cells over the object's box alone, on the
        window of spectrum ``xf`` (the context's cells left out)."""
        hf = self._weighted_filter(self.box_cells)
        return sfft.irfft2(np.sum(hf * xf, axis=0), s=self.hann.shape)

    def _centre_max(self, r: np.ndarray) -> float:
        """The best response within a tenth of the target of the window centre (where the
        estimate sits; it is a particle mean, not the peak)."""
        th, tw = r.shape
        rad = max(1, int(round(0.1 * self.target_px)))
        cy, cx = (th - 1) / 2, (tw - 1) / 2
        y0, y1 = int(np.floor(cy)) - rad, int(np.ceil(cy)) + rad + 1
        x0, x1 = int(np.floor(cx)) - rad, int(np.ceil(cx)) + rad + 1
        return float(r[max(y0, 0):y1, max(x0, 0):x1].max())

    # -- re-detection ------------------------------------------------------------------
    def detect(self, ctx: FrameContext, centre, scale: float, max_peaks: int = 3) -> Scan:
        """Where the object may be in the whole frame: the highest peaks of the long-term
        filter's response over the frame at ``scale`` (relative to the first box), in
        units of its typical peak. Only the filter's cells over the object's box are
        used: the rest learned the background around the object, which stays where the
        object was.

        The frame is resampled to template pixels and correlated with the filters once
        (FFT); a frame wider than :data:`MAX_DETECT_PX` template pixels is scanned in a
        window of that side around ``centre``. Returns a :class:`Scan`: the peaks'
        centres ``(m, 2)`` in image pixels, their relative responses ``(m,)`` and
        standard scores (in standard deviations of the map above its mean), highest
        first, at least a tenth of the object apart and with the whole box inside the
        frame (``m <= max_peaks``), and the number of independent values the map holds
        (its cells over the square of twice the target peak's width); cached per frame."""
        self.require_model()

        def make():
            grey = grey_frame(ctx)
            H, W = grey.shape
            step = self.ref_size * float(scale) / np.array(self.shape)  # image px / cell
            ow = min(int(np.ceil(W / step[0])), MAX_DETECT_PX)
            oh = min(int(np.ceil(H / step[1])), MAX_DETECT_PX)
            size = np.array([ow, oh]) * step
            c = np.asarray(centre, dtype=float)
            mid = np.array([W, H]) / 2.0 - 0.5
            # the scanned region: the frame, or a window around the estimate within it
            lo = np.clip(c - size / 2, -0.5, np.array([W, H]) - 0.5 - size)
            rc = np.where(size >= np.array([W, H]), mid, lo + size / 2)
            feats = window_features(grey, rc, size, (ow, oh), self.n_orient)
            th, tw = self.hann.shape
            full = (oh + th - 1, ow + tw - 1)
            fshape = (sfft.next_fast_len(full[0], real=True),
                      sfft.next_fast_len(full[1], real=True))
            zf = sfft.rfft2(feats, s=fshape, axes=(-2, -1))
            num, den, peak = self.memory
            h = sfft.irfft2(np.conj(num) / self._regularised(den), s=(th, tw))
            # the filter's cells over the object's box only: its context (padding)
            # learned the background around the object, which stays where the object was
            h = np.fft.fftshift(h, axes=(-2, -1)) * self.box_cells
            hf = sfft.rfft2(h, s=fshape, axes=(-2, -1))
            best = sfft.irfft2(np.sum(hf * zf, axis=0), s=fshape)
            best = best[th // 2:th // 2 + oh, tw // 2:tw // 2 + ow] / peak
            # only where the whole box is in the frame: a box across the border reads
            # the border's replicated pixels
            half = self.ref_size * float(scale) / (1 + self.padding) / 2
            x0, y0 = rc - size / 2
            gx = x0 + (np.arange(ow) + 0.5) * step[0] - 0.5
            gy = y0 + (np.arange(oh) + 0.5) * step[1] - 0.5
            ok_x = (gx - half[0] >= -0.5) & (gx + half[0] <= W - 0.5)
            ok_y = (gy - half[1] >= -0.5) & (gy + half[1] <= H - 0.5)
            if not ok_x.any() or not ok_y.any():
                return Scan(np.zeros((0, 2)), np.zeros(0), np.zeros(0), 0.0)
            valid = ok_y[:, None] & ok_x[None, :]
            mean, sd = float(best[valid].mean()), float(best[valid].std()) + 1e-12
            best = np.where(valid, best, -np.inf)
            cells, vals = response_peaks(best, max(1, int(round(0.1 * self.target_px))),
                                         max_peaks)
            keep = np.isfinite(vals)
            xy = rc - size / 2 + (cells[keep] + 0.5) * step - 0.5
            # the map is correlated over about the target peak's width: one independent
            # value per (2 sigma)^2 cells
            corr = 2.0 * self.sigma * self.target_px
            return Scan(xy, vals[keep], (vals[keep] - mean) / sd,
                        float(valid.sum()) / max(corr * corr, 1.0))

        return self._cached(ctx, ("cf-detect", max_peaks), make)

    # -- scoring -----------------------------------------------------------------------
    def _window(self, ctx: FrameContext, centre, levels, angle: float, key):
        """Response maps of one window turned by ``angle``: one per scale level, and with
        an angle component two more at ``angle ± angle_step`` and the middle scale (None
        without); cached on the frame."""
        def make():
            maps = np.stack([self._response(self._spectrum(ctx, centre, s, angle))
                             for s in levels]) / self.peak
            if self.angle_index is None:
                return maps, None
            mid = float(levels[len(levels) // 2])
            turned = np.stack([self._response(self._spectrum(ctx, centre, mid, a))
                               for a in (angle - self.angle_step, angle + self.angle_step)])
            return maps, turned / self.peak

        return self._cached(ctx, ("cf-window",) + key, make)

    def _maps(self, x: np.ndarray, ctx: FrameContext):
        """This frame's first window: its centre (the particles' mean), scale levels
        (around their mean scale) and maps (computed at the first call in a frame and
        cached on it)."""
        def make():
            self._check_camera(ctx)
            b = self.boxes(x)
            base = mean_box_size(b) / self.ref_scale
            levels = base * self.scale_step ** (np.arange(self.scales) - self.scales // 2)
            centre = b[:, :2].mean(axis=0)
            quarter = self.ref_size * base / 4
            if self.windows > 1 and not _one_cloud(b[:, :2], centre, quarter):
                centre = self._next_centre(b[:, :2], quarter)
            angle = 0.0 if self.angle_index is None else float(x[:, self.angle_index].mean())
            return centre, levels, angle, self._window(ctx, centre, levels, angle, ())

        return self._cached(ctx, ("cf-response",), make)

    def relative_response(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N,)`` response at each particle, in units of the typical peak.

        The first window is centred on the particles' mean. With ``windows > 1``, and
        unless nine in ten particles lie within a quarter window of it (one cloud, a few
        stragglers: the usual case; otherwise a proposal put some near a far-away peak,
        :meth:`detect`), each window is centred on a mode
        of the particles not yet read — the one with the most of them within a quarter
        window — and reads those within a quarter window of its centre, so every
        particle is read near the middle of a window, where the maps are comparable; at
        most ``windows`` windows, the last reading every particle inside it, and a
        particle outside them all scores ``floor``."""
        self.require_model()
        centre, levels, angle, maps = self._maps(x, ctx)
        b = self.boxes(x)
        angles = (np.zeros(len(b)) if self.angle_index is None
                  else np.asarray(x[:, self.angle_index], float))
        quarter = self.ref_size * float(levels[len(levels) // 2]) / 4
        if self.windows == 1 or _one_cloud(b[:, :2], b[:, :2].mean(axis=0), quarter):
            return self._read(maps, levels, angle, centre, b, angles)[0]
        out = np.full(len(b), self.floor)
        todo = np.arange(len(b))
        for k in range(self.windows):
            if k > 0:
                centre = self._next_centre(b[todo, :2], quarter)
                maps = self._window(ctx, centre, levels, angle,
                                    (round(centre[0], 3), round(centre[1], 3)))
            val, inside = self._read(maps, levels, angle, centre, b[todo], angles[todo])
            if k < self.windows - 1:
                inside &= np.all(np.abs(b[todo, :2] - centre) <= quarter, axis=1)
            out[todo[inside]] = val[inside]
            todo = todo[~inside]
            if todo.size == 0:
                break
        return out

    @staticmethod
    def _next_centre(xy: np.ndarray, quarter: np.ndarray) -> np.ndarray:
        """Among points ``xy``, the one with the most others within ``quarter`` of it."""
        d = np.abs(xy[:, None, :] - xy[None, :, :]) <= quarter
        return xy[int(np.argmax(np.sum(d.all(axis=2), axis=1)))]

    @staticmethod
    def _sample(maps: np.ndarray, which, centre, b, step, angle):
        """Bilinear reading of the maps ``maps[which]`` (``which``: one index per box, or
        one for all) of windows turned by ``angle`` (per box or one) with cells ``step``
        (image px, per box or one) at the boxes' centres; and whether each lies in its
        window."""
        _, th, tw = maps.shape
        c, s = np.cos(angle), np.sin(angle)
        dx, dy = b[:, 0] - centre[0], b[:, 1] - centre[1]
        u = (c * dx + s * dy) / step[..., 0] + (tw - 1) / 2
        v = (-s * dx + c * dy) / step[..., 1] + (th - 1) / 2
        inside = (u >= 0) & (u <= tw - 1) & (v >= 0) & (v <= th - 1)
        u0 = np.clip(np.floor(u).astype(np.intp), 0, tw - 2)
        v0 = np.clip(np.floor(v).astype(np.intp), 0, th - 2)
        fu, fv = np.clip(u - u0, 0, 1), np.clip(v - v0, 0, 1)
        val = ((1 - fv) * ((1 - fu) * maps[which, v0, u0] + fu * maps[which, v0, u0 + 1])
               + fv * ((1 - fu) * maps[which, v0 + 1, u0]
                       + fu * maps[which, v0 + 1, u0 + 1]))
        return val, inside

    def _read(self, window, levels, angle, centre, b, angles) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear (position), linear (log-scale) and, with an angle component, linear
        (angle) reading of a window's maps at the boxes ``b`` turned by ``angles``:
        values and whether each box's centre lies in the window."""
        maps, turned = window
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
        inside_all = np.ones(len(b), dtype=bool)
        cells = np.array(self.shape, dtype=float)
        for lev, wgt in ((l0, 1 - fl), (l1, fl)):
            # particle centre in the level's window: template px
            step = self.ref_size[None, :] * levels[lev][:, None] / cells[None]
            val, inside = self._sample(maps, lev, centre, b, step, angle)
            out += wgt * np.where(inside, val, self.floor)
            inside_all &= inside | (wgt == 0)
        if turned is not None:  # the change of response with the particle's own angle
            step = self.ref_size * float(levels[n_lev // 2]) / cells
            mid, ok = self._sample(maps, n_lev // 2, centre, b, step, angle)
            t = np.clip((angles - angle) / self.angle_step, -1.0, 1.0)
            side = (t >= 0).astype(np.intp)  # turned[0]: angle - step, turned[1]: + step
            val, ins = self._sample(turned, side, centre, b, step,
                                    angle + (2 * side - 1) * self.angle_step)
            out += np.where(ok & ins, np.abs(t) * (val - mid), 0.0)
        return out, inside_all

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return self.lam * self.relative_response(x, ctx)
