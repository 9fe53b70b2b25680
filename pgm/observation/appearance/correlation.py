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

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft as sfft

from pgm.core.frame import FrameContext
from pgm.core.learned import LearnedState
from pgm.core.numerics import check_finite_param
from pgm.observation.camera_motion import CameraMotionEstimator

from .cf_context import LearnedContext
from .cf_features import (
    Scan,
    _fast_even,
    chroma_frame,
    filter_of,
    patch_features,
    peak_to_sidelobe,
    response_peaks,
    ridge,
    window_features,
)
from .cf_reading import ResponseReading
from .cf_redetect import RedetectionScan
from .likelihoods import BoxAppearanceLikelihood, bounded_int, grey_frame

__all__ = ["CorrelationFilterLikelihood", "window_features", "patch_features",
           "peak_to_sidelobe", "response_peaks", "Scan", "filter_of", "ridge"]

#: widest search window, in template pixels per side (``target_px · (1 + padding)``):
#: the window's features and spectra are ``(1 + n_orient) ·`` its area, per scale level
MAX_WINDOW_PX = 512
#: frames are checked for a still camera (while the context is learned) at most this
#: many pixels wide: the verdicts on the shared sequences are those at 640
CAMERA_CHECK_PX = 320
#: how the camera is checked: every frame's corners found anew and followed in wide
#: windows, the frame shrunk to exactly ``CAMERA_CHECK_PX`` (the settings the single-object
#: defaults were chosen with)
CAMERA_CHECK = {"max_side": CAMERA_CHECK_PX, "max_corners": 400, "win_size": 21,
                "pyramid_levels": 3, "track": False, "halve": False}
#: windows a frame's particles may open (:meth:`CorrelationFilterLikelihood.relative_response`):
#: the first at the particles' mean, the others at particles outside every window so far
MAX_WINDOWS = 4


@dataclass
class CorrelationFilterState(LearnedState):
    """What a :class:`CorrelationFilterLikelihood` learns: the window's geometry (from
    the first box), the filter, its long-term memory and context, and the last frame's
    response."""

    shape: tuple[int, int] | None = None  # (tw, th) of the window in template px
    ref_size: np.ndarray | None = None  # the window (px) at scale 1
    ref_scale: float | None = None  # sqrt(w h) of the first box
    hann: np.ndarray | None = None  # (th, tw) cosine window
    box_cells: np.ndarray | None = None  # (th, tw) cells over the object's box
    gf: np.ndarray | None = None  # the Gaussian label's spectrum
    num: np.ndarray | None = None  # (C, th, tw) complex numerator  conj(G) · X_c
    den: np.ndarray | None = None  # (th, tw) real denominator  Σ_c |X_c|²
    peak: float | None = None  # running mean of the peak response at the estimates
    last_response: float | None = None  # relative response at the last estimate
    last_psr: float | None = None  # peak-to-sidelobe ratio of the map at the last estimate
    memory: tuple | None = None  # the long-term filter: (num, den, peak)
    _scan_filter: tuple | None = None  # the scan's filter spectrum, kept while unchanged
    context: np.ndarray | None = None  # (th, tw) probability a cell moves with the object
    object_peak: float | None = None  # running mean peak of the filter's box cells alone
    camera_moved_at: int | None = None  # the frame where the camera was found moving
    _first_frames: Any = None  # the check of each of the first frames (see update)
    _checked: int = 0  # frames it checked: the context weights the filter from one on
    _checked_index: int | None = None  # the last frame checked
    _camera: Any = None  # the still-camera check while the context is learned
    _mask_cache: Any = None
    _last_seen: tuple | None = None  # (features, centre, scale, angle) last learned


class CorrelationFilterLikelihood(LearnedContext, RedetectionScan, ResponseReading,
                                  BoxAppearanceLikelihood):
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
    colour : bool
        Two more channels, the window's chroma (CIE Lab ``a*``, ``b*``:
        :func:`~pgm.observation.appearance.cf_features.chroma_frame`), as the colour
        features of CSR-DCF and ECO add to gradients (False, the default: grey and
        gradients only; a grey video's chroma is zero).
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
    scan_side : float
        The side of the region :meth:`detect` scans, in object sizes (``sqrt(w h)`` at
        the scale scanned), centred on the estimate and kept inside the frame (the whole
        frame when it is smaller; at most ``cf_features.MAX_DETECT_PX`` template
        pixels). A scan costs the region's area in template pixels: on UAV10-group3 (a
        person 21 px across in a 1280x720 frame) 11 ms at 10 sizes, 114 ms at 32. With
        re-detection (``--redetect 0.5``, four seeds) 10 and 32 sizes give Biker and
        MotorRolling the same boxes and UAV10-group3 a success AUC of 0.171 against
        0.174: an object lost there is found again near where it was lost. Raise it
        for one that may come back far away.
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
        ``floor``; more (at most :data:`MAX_WINDOWS`; re-detection sets it) at the
        particles a proposal put near peaks of the scan (:meth:`open_windows_at`).
    """

    model_attr = "num"
    State = CorrelationFilterState

    def __init__(self, variable: str, *, lam: float = 60.0, padding: float = 2.0,
                 target_px: float = 32.0, n_orient: int = 6, sigma: float = 0.1,
                 reg: float = 1e-2, adapt_rate: float = 0.02, gate: float = 0.5,
                 scales: int = 3, scale_step: float = 1.05, floor: float = -0.2,
                 memory_rate: float = 0.002, context_rate: float = 0.0, windows: int = 1,
                 colour: bool = False, scan_side: float = 10.0,
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
        if colour not in (True, False, 0, 1):
            raise ValueError(f"factor {n!r}: colour is true or false, got {colour!r}")
        self.colour = bool(colour)
        self.scan_side = float(check_finite_param(f"{n}.scan_side", scan_side, positive=True))
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

    @property
    def confidence_response(self) -> float | None:
        """``log`` of the filter's response at the last estimate over its running mean
        peak (floored at 0.01; None before the first update): the second feature
        :func:`pgm.core.readout.confidence` may calibrate (``response_slope``). A filter
        held by a corner of the background can keep a sharp map (a high PSR) while its
        response there stays a fraction of the target's."""
        if self.last_response is None:
            return None
        return float(np.log(max(self.last_response, 1e-2)))

    def params(self) -> dict[str, Any]:
        p = {"lam": self.lam, "padding": self.padding, "target_px": self.target_px,
             "n_orient": self.n_orient, "sigma": self.sigma, "reg": self.reg,
             "adapt_rate": self.adapt_rate, "gate": self.gate, "scales": self.scales,
             "scale_step": self.scale_step, "floor": self.floor,
             "memory_rate": self.memory_rate, "context_rate": self.context_rate,
             "windows": self.windows, "scan_side": self.scan_side,
             "angle_index": self.angle_index, "angle_step": self.angle_step,
             "box_indices": list(self.box_indices)}
        if self.colour:
            p["colour"] = True
        return p

    # -- geometry ----------------------------------------------------------------------
    def _setup(self, box: np.ndarray) -> None:
        w, h = float(box[2]), float(box[3])
        k = self.target_px / np.sqrt(w * h)  # template px per image px
        tw = _fast_even(k * w * (1 + self.padding))
        th = _fast_even(k * h * (1 + self.padding))
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
        return self._window_features(ctx, centre, self.ref_size * scale, self.shape, angle)

    def _window_features(self, ctx: FrameContext, centre, size, shape,
                         angle: float = 0.0) -> np.ndarray:
        """The features of the window of ``size`` px at ``centre``, resampled to
        ``shape``: grey and gradients, and the chroma with ``colour``."""
        chroma = (ctx.cached(("chroma-lab",), lambda: chroma_frame(ctx.image))
                  if self.colour and ctx.image is not None else None)
        return window_features(grey_frame(ctx), centre, size, shape, self.n_orient, angle,
                               chroma)

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
            self._camera = CameraMotionEstimator("auto", **CAMERA_CHECK)
            self._first_frames = CameraMotionEstimator("on", **CAMERA_CHECK)
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

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return self.lam * self.relative_response(x, ctx)
