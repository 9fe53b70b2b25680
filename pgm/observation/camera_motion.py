"""Global (camera) motion between consecutive frames, for moving-camera video.

:class:`CameraMotionEstimator` tracks sparse corners from the previous frame to the
current one (OpenCV: Shi–Tomasi corners, pyramidal Lucas–Kanade flow) and fits a
similarity transform — rotation, uniform scale, translation — robustly to the matches
(``cv2.estimateAffinePartial2D`` with RANSAC), so that people moving through the scene
are outliers to the background's motion. A fit is taken for the camera's only when its
inliers span at least half the image's width and height and it explains more corners
than "nothing moved" does: otherwise it is a moving object's motion (a face filling the
frame, people on a plain background) and the frame gets none. The result ``[M | t]`` maps a pixel of the
previous frame to the current one; it is attached to the frame
(:attr:`pgm.core.frame.FrameContext.camera_motion`) and the engine's transition rules
move every target's past states through it (:func:`pgm.core.motion.warp_states`).

Frames are analysed halved (``INTER_AREA``) until at most ``max_side`` (480) pixels wide
— a 1920x1080 frame at 480x270, a 640x480 one at 320x240 — and the motion is rescaled to
full resolution. The corners a fit explained are followed into the next frame: new ones
are found only when fewer than half of ``max_corners`` (200) remain or the followed ones
give no fit; the Lucas–Kanade pyramid is deep enough to follow a pan of ``MAX_PAN`` (2)
frame widths a second at the video's frame rate; Lucas–Kanade works in 9-pixel windows
and stops refining a point once it moves by less than 0.03 of an analysed pixel. On
MOT16-11 (a camera walking with the crowd) that costs 1.2 ms a frame against 7.5 for
finding 400 corners anew on every frame shrunk to 640 wide, 21-pixel windows (the same
run), and is as close to a finer estimate (960 wide, 1000 corners) as that was: median
corner error 0.41 px against 0.43, 95th percentile 1.30 against 1.34, where the camera
moves the image's corners by 5.8 px a frame (``python benchmarks/speed.py --sections
camera``). ``mode="auto"`` attaches a
frame's motion only when the camera is
*moving*: the frame's fit moves some image corner by more than ``min_shift`` pixels
(default 1 px), and so did at least ``min_fraction`` (80 %) of the last ``window`` (20)
frames' fits. A still camera's estimates stay below 1 px; a large object crossing a still
camera (FaceOcc1's face and magazine) can pass the per-frame tests for a few frames, not
for 16 of 20: 18 of FaceOcc1's 888 frames are compensated, none of Crossing's,
PETS09-S2L1's, TUD-Campus's, TUD-Stadtmitte's or Tiger1's, against 284 of MOT16-11's 300 (a
moving camera) and 243 of David's 462 (a panning camera). A still camera is found
cheaply: ``auto`` estimates a frame only when its verdict can change what is reported
(while fewer than 16 of the window's frames could have moved, nothing is reported
whatever this frame did), and estimates the verdicts it skipped, from the grey images
it keeps, once a frame does move; what it reports is what estimating every frame
reports — the same verdicts, and the same motions up to the sub-pixel differences of
corners followed along another path (exactly the same with ``track=False``) — on a quarter
of a still camera's frames (PETS09-S2L1: 59 of 240 estimated, MOT16-11: 299 of 300).
The runners turn it on (``"auto"``) for multi-target models and leave it off for one
object, whose camera usually follows it (see :func:`pgm.app.runner.track`).

``method="botsort"`` estimates the motion as BoT-SORT's sparse optical flow does (the
``trackers`` package's ``CMC(method="sparseOptFlow", downscale=2)``,
:func:`estimate_sparse_flow`): grey images halved, up to 1000 Shi–Tomasi corners (quality
0.01, 1 px apart, 3 px blocks), Lucas–Kanade with OpenCV's defaults, a partial affine fit
by RANSAC with its defaults and none of the checks above — a fit is whatever the corners
say, a still camera's included (a few tenths of a pixel of jitter per frame). With
``mode="on"`` every frame gets it, as BoT-SORT applies it (:mod:`pgm.models.botsort`).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from pgm.core.numerics import check_finite_param

__all__ = ["CameraMotionEstimator", "estimate_camera_motion", "estimate_sparse_flow", "MODES",
           "METHODS", "MAX_PAN", "track_camera_motion"]

MODES = ("auto", "on", "off")
#: how a frame's motion is estimated: the toolkit's checked similarity fit, or BoT-SORT's
#: sparse optical flow (the ``trackers`` package's, every fit taken)
METHODS = ("checked", "botsort")
#: the fastest pan the default estimator follows, in frame widths per second (the
#: Lucas–Kanade pyramid is made deep enough for it at the video's frame rate)
MAX_PAN = 2.0
#: BoT-SORT's corners (``trackers`` 2.6.1 ``CMCConfig``: ``sof_*``)
BOTSORT_CORNERS = {"maxCorners": 1000, "qualityLevel": 0.01, "minDistance": 1, "blockSize": 3,
                   "useHarrisDetector": False, "k": 0.04}


_LK_STOP = cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS


#: halvings of a colour frame done at once, before its grey is taken (:func:`_grey`)
COLOUR_HALVINGS = 2


def _grey(image: np.ndarray, scale: float = 1.0, halvings: int = 0) -> np.ndarray:
    """The grey image halved ``halvings`` times (each pixel the mean of the 2x2 below it,
    ``INTER_AREA``: a halving is several times cheaper than one arbitrary shrink), then
    shrunk by ``scale``.

    A colour frame's first ``k = min(halvings, COLOUR_HALVINGS)`` halvings are one
    bilinear shrink by ``2^k`` before its grey is taken: each pixel the mean of the 2x2
    at the centre of its ``2^k`` block (at ``k = 1`` the whole block, as a halving), so
    the colour conversion reads a ``4^k``-th of the frame's pixels, not every one (its
    cost and accuracy: ``docs/results.md``, issue 39)."""
    if image.ndim == 3 and halvings > 0:
        k = min(halvings, COLOUR_HALVINGS)
        h, w = image.shape[:2]
        image = cv2.resize(image, (max(1, w >> k), max(1, h >> k)),
                           interpolation=cv2.INTER_LINEAR)
        halvings -= k
    img = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    for _ in range(halvings):
        h, w = img.shape[:2]
        img = cv2.resize(img, (max(1, w // 2), max(1, h // 2)), interpolation=cv2.INTER_AREA)
    if scale != 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    return img


def estimate_camera_motion(prev_grey: np.ndarray, grey: np.ndarray, *, max_corners: int = 400,
                           ransac_threshold: float = 1.0, min_coverage: float = 0.5,
                           win_size: int = 21, pyramid_levels: int = 3
                           ) -> tuple[np.ndarray | None, int]:
    """Similarity ``[M | t]`` ``(2, 3)`` taking ``prev_grey`` pixels to ``grey``, and the
    number of RANSAC inliers.

    ``None, 0`` when the image motion is not the camera's: too few corners followed; a
    fit whose inliers do not span ``min_coverage`` of the image's width and height (a
    moving object, not the background); or a fit that explains fewer corners than
    "nothing moved" does (a still camera watching people walk). Corners: up to
    ``max_corners`` Shi–Tomasi corners of ``prev_grey``, followed by Lucas–Kanade flow in
    ``win_size`` windows over ``pyramid_levels`` levels.
    """
    A, n, _ = track_camera_motion(prev_grey, grey, None, max_corners=max_corners,
                                  ransac_threshold=ransac_threshold,
                                  min_coverage=min_coverage, win_size=win_size,
                                  pyramid_levels=pyramid_levels)
    return A, n


def track_camera_motion(prev_grey: np.ndarray, grey: np.ndarray, points: np.ndarray | None,
                        *, max_corners: int = 400, ransac_threshold: float = 1.0,
                        min_coverage: float = 0.5, win_size: int = 21,
                        pyramid_levels: int = 3, flow_epsilon: float = 0.01
                        ) -> tuple[np.ndarray | None, int, np.ndarray | None]:
    """:func:`estimate_camera_motion` from given ``points`` of ``prev_grey`` (``(n, 1, 2)``
    float32; None: its corners, found now), and the inliers' positions in ``grey`` (the
    points to follow into the next frame; None without a fit). Lucas–Kanade stops at a
    level after 30 iterations or when an iteration moves a point by less than
    ``flow_epsilon`` analysed pixels (OpenCV's default: 0.01)."""
    check_finite_param("flow_epsilon", flow_epsilon, positive=True)
    if points is None:
        points = cv2.goodFeaturesToTrack(prev_grey, maxCorners=max_corners, qualityLevel=0.01,
                                         minDistance=8, blockSize=7)
    if points is None or len(points) < 8:
        return None, 0, None
    nxt, status, _ = cv2.calcOpticalFlowPyrLK(prev_grey, grey, points, None,
                                              winSize=(win_size, win_size),
                                              maxLevel=pyramid_levels,
                                              criteria=(_LK_STOP, 30, float(flow_epsilon)))
    ok = status.reshape(-1) == 1
    if ok.sum() < 8:
        return None, 0, None
    p0, p1 = points[ok].reshape(-1, 2), nxt[ok].reshape(-1, 2)
    A, inliers = cv2.estimateAffinePartial2D(p0, p1, method=cv2.RANSAC,
                                             ransacReprojThreshold=ransac_threshold,
                                             maxIters=2000, confidence=0.995)
    if A is None or inliers is None or not np.all(np.isfinite(A)):
        return None, 0, None
    inl = inliers.reshape(-1).astype(bool)
    n = int(inl.sum())
    n_still = int(np.count_nonzero(np.linalg.norm(p1 - p0, axis=1) < ransac_threshold))
    h, w = prev_grey.shape[:2]
    span = np.ptp(p0[inl], axis=0) if n else np.zeros(2)
    if n < 8 or n <= n_still or span[0] < min_coverage * w or span[1] < min_coverage * h:
        return None, 0, None
    return A.astype(float), n, p1[inl].reshape(-1, 1, 2).astype(np.float32)


def sparse_flow_corners(grey: np.ndarray) -> np.ndarray | None:
    """BoT-SORT's corners of a grey image (:data:`BOTSORT_CORNERS`; None: none found)."""
    return cv2.goodFeaturesToTrack(grey, mask=None, **BOTSORT_CORNERS)


def estimate_sparse_flow(prev_grey: np.ndarray, grey: np.ndarray,
                         prev_corners: np.ndarray | None = None) -> np.ndarray | None:
    """BoT-SORT's motion ``[M | t]`` ``(2, 3)`` taking ``prev_grey`` pixels to ``grey``
    (the ``trackers`` package's sparse optical flow, float32 as it computes it): the
    previous image's corners (``prev_corners``, else found now) followed by Lucas–Kanade,
    a partial affine fit by RANSAC on those it followed; None where it has no fit (no
    corners, at most four followed, a failed fit), which the package takes as the
    identity."""
    if prev_grey.shape != grey.shape:
        return None
    pts = sparse_flow_corners(prev_grey) if prev_corners is None else prev_corners
    if pts is None:
        return None
    nxt, status, _ = cv2.calcOpticalFlowPyrLK(prev_grey, grey, pts, None)
    if status is None or nxt is None:
        return None
    good = status.reshape(-1) != 0
    if int(good.sum()) <= 4:
        return None
    A, _ = cv2.estimateAffinePartial2D(pts[good], nxt[good], method=cv2.RANSAC)
    return None if A is None else A.astype(np.float32)


class CameraMotionEstimator:
    """Estimates each frame's camera motion from the previous frame.

    Parameters
    ----------
    mode : {"auto", "on", "off"}
        ``"auto"``: report a frame's motion only when significant (see module docs);
        ``"on"``: always report it; ``"off"``: never (every call returns ``None``).
    min_shift : float
        ``"auto"``: the smallest corner displacement (px) that counts as camera motion.
    window, min_fraction : int, float
        ``"auto"``: the camera counts as moving when at least ``min_fraction`` of the
        last ``window`` frames (this one included) moved by ``min_shift``.
    max_side : int
        Frames are analysed at most this many pixels wide: halved (``INTER_AREA``) until
        they are (a 1920x1080 frame at 480x270, a 1280x720 one at 320x180), or with
        ``halve=False`` shrunk to exactly ``max_side`` (one arbitrary ``INTER_AREA``
        shrink of the grey frame: several times a halving's cost).
    max_corners, win_size : int
        ``"checked"``: corners followed and the Lucas–Kanade window (analysed pixels).
    flow_epsilon : float
        ``"checked"``: Lucas–Kanade's iterations stop when a point moves by less than this
        (analysed pixels; 0.03 of a pixel at 480 wide is 0.12 of a 1080p pixel, a quarter
        of the estimate's median error against a finer one).
    pyramid_levels : int, optional
        ``"checked"``: the Lucas–Kanade pyramid's levels (:func:`track_camera_motion`). By
        default the fewest (at least 2) whose reach, about ``win_size // 2 · 2**levels``
        analysed pixels, follows a pan of :data:`MAX_PAN` frame widths per second at the
        video's ``fps`` (1080p at 30 frames/s: 3 levels; 1280x720 at 10 frames/s: 4).
    fps : float, optional
        The video's frame rate, for the default ``pyramid_levels`` (None: 30).
    track : bool
        ``"checked"``: the corners a fit explained are followed into the next frame, and
        new corners are found only when fewer than half of ``max_corners`` remain or the
        followed ones give no fit (saves finding corners on most frames; on MOT16-11 as
        close to a finer estimate as finding 400 corners anew on every 640-pixel frame:
        ``python benchmarks/speed.py --sections camera``).
    method : {"checked", "botsort"}
        ``"checked"``: the toolkit's similarity fit with its checks
        (:func:`estimate_camera_motion`); ``"botsort"``: BoT-SORT's sparse optical flow
        on frames shrunk ``downscale`` times (:func:`estimate_sparse_flow`; ``max_side``
        unused).
    downscale : int
        ``"botsort"``: the integer factor frames are shrunk by (2, as the package).
    """

    def __init__(self, mode: str = "auto", *, min_shift: float = 1.0, window: int = 20,
                 min_fraction: float = 0.8, max_side: int = 480, method: str = "checked",
                 downscale: int = 2, max_corners: int = 200, win_size: int = 9,
                 pyramid_levels: int | None = None, fps: float | None = None,
                 track: bool = True, halve: bool = True, flow_epsilon: float = 0.03):
        if mode not in MODES:
            raise ValueError(f"camera motion mode must be one of {MODES}, got {mode!r}")
        if method not in METHODS:
            raise ValueError(f"camera motion method must be one of {METHODS}, got {method!r}")
        if isinstance(downscale, bool) or int(downscale) != downscale or downscale < 1:
            raise ValueError(f"downscale must be a positive integer, got {downscale!r}")
        self.method, self.downscale = method, int(downscale)
        for name, v in (("max_corners", max_corners), ("win_size", win_size),
                        ("pyramid_levels", 1 if pyramid_levels is None else pyramid_levels + 1)):
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if fps is not None and not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        check_finite_param("flow_epsilon", flow_epsilon, positive=True)
        self.max_corners, self.win_size = int(max_corners), int(win_size)
        self.flow_epsilon = float(flow_epsilon)
        self.levels_given = None if pyramid_levels is None else int(pyramid_levels)
        self.pyramid_levels, self.track = self.levels_given or 2, bool(track)
        self.fps = 30.0 if fps is None else float(fps)
        self.halve = bool(halve)
        #: ``"checked"`` with ``track``: the analysed image of the last fit and the corners
        #: it explained, in that image (followed when the next estimate starts from it)
        self._followed: tuple[np.ndarray, np.ndarray] | None = None
        #: ``"botsort"``: the corners of the newest analysed image (it, its corners)
        self._corners: tuple[np.ndarray, np.ndarray | None] | None = None
        if not np.isfinite(min_shift) or min_shift < 0:
            raise ValueError(f"min_shift must be a non-negative number, got {min_shift!r}")
        if int(window) < 1 or not 0.0 <= float(min_fraction) <= 1.0:
            raise ValueError(f"need window >= 1 and min_fraction in [0, 1], got {window!r}, "
                             f"{min_fraction!r}")
        self.mode, self.min_shift, self.max_side = mode, float(min_shift), int(max_side)
        self.window, self.min_fraction = int(window), float(min_fraction)
        #: ``auto``: the last ``window`` frames' verdicts, each True (moved), False or
        #: None (not estimated: it could not change a result), with the analysed grey
        #: images of those frames and the one before (to estimate a verdict later)
        self._recent: list[bool | None] = []
        self._greys: list[np.ndarray] = []
        self._scale = 1.0
        self._halvings = 0
        self._size: tuple[int, int] | None = None
        #: frames whose motion was reported (``auto``: found significant)
        self.frames_moved = 0
        #: frames whose motion was estimated (``auto`` skips those that cannot matter)
        self.frames_estimated = 0
        #: seconds spent in the calls so far (inference time, as the runners report it)
        self.seconds = 0.0

    def _estimate(self, prev: np.ndarray, grey: np.ndarray) -> np.ndarray | None:
        """The motion ``prev → grey`` in full-resolution pixels (None: not the camera's)."""
        self.frames_estimated += 1
        if self.method == "botsort":
            return self._sparse_flow(prev, grey)
        followed = self._followed
        points = (followed[1] if self.track and followed is not None and followed[0] is prev
                  and len(followed[1]) >= self.max_corners // 2 else None)
        settings = {"max_corners": self.max_corners, "win_size": self.win_size,
                    "pyramid_levels": self.pyramid_levels, "flow_epsilon": self.flow_epsilon}
        A, _, nxt = track_camera_motion(prev, grey, points, **settings)
        if A is None and points is not None:  # the followed corners fail: find them anew
            A, _, nxt = track_camera_motion(prev, grey, None, **settings)
        self._followed = None if nxt is None else (grey, nxt)
        if A is not None:
            A = A.copy()
            A[:, 2] /= self._scale  # translation back to full-resolution pixels
        return A

    def _sparse_flow(self, prev: np.ndarray, grey: np.ndarray) -> np.ndarray | None:
        """BoT-SORT's estimate ``prev → grey``, its translation in full-resolution pixels
        (as the package: the float32 fit, its translation times ``downscale``). The
        corners of ``grey`` are kept for the next frame; as the package, a frame without
        corners of its own gets no motion."""
        cached = self._corners
        prev_corners = cached[1] if cached is not None and cached[0] is prev else \
            sparse_flow_corners(prev)
        corners = sparse_flow_corners(grey)
        self._corners = (grey, corners)
        if prev_corners is None or corners is None:
            return None
        A = estimate_sparse_flow(prev, grey, prev_corners)
        if A is None:
            return None
        A[:, 2] *= np.float32(self.downscale)
        return A.astype(float)

    def _grey(self, image: np.ndarray) -> np.ndarray:
        """The analysed grey image of ``image`` (``"botsort"``: shrunk as the package)."""
        if self.method != "botsort":
            return _grey(image, halvings=self._halvings) if self.halve else \
                _grey(image, self._scale)
        img = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if self.downscale > 1:
            h, w = img.shape[:2]
            img = cv2.resize(img, (max(1, w // self.downscale), max(1, h // self.downscale)))
        return img

    def _moved(self, A: np.ndarray | None) -> bool:
        w, h = self._size
        return A is not None and self.corner_shift(A, w, h) >= self.min_shift

    def __call__(self, image: np.ndarray) -> np.ndarray | None:
        """The motion from the previous image to ``image`` (``None`` for the first frame,
        when off, when not significant under ``auto``, or when it cannot be estimated);
        the time it took is added to :attr:`seconds`."""
        t0 = time.perf_counter()
        try:
            return self._motion(image)
        finally:
            self.seconds += time.perf_counter() - t0

    def _motion(self, image: np.ndarray) -> np.ndarray | None:
        if self.mode == "off" or image is None:
            return None
        h, w = image.shape[:2]
        grey = None
        if self._size != (w, h):  # first frame (or a size change): start afresh
            self._size = (w, h)
            self._recent, self._greys = [], []
            self._halvings = 0
            while self.halve and max(w, h) >> self._halvings > self.max_side:
                self._halvings += 1
            self._scale = (max(1, w >> self._halvings) / w if self.halve
                           else min(1.0, self.max_side / max(w, h)))
            if self.levels_given is None:  # follow a pan of MAX_PAN widths a second
                reach = MAX_PAN * w * self._scale / self.fps / max(self.win_size // 2, 1)
                self.pyramid_levels = max(2, int(np.ceil(np.log2(max(reach, 1.0)))))
        else:
            grey = self._grey(image)
        if grey is None:
            self._greys = [self._grey(image)]
            return None
        if self.mode == "on":
            A = self._estimate(self._greys[-1], grey)
            self._greys = [grey]
            if A is not None:
                self.frames_moved += 1
            return A
        return self._auto(grey)

    def _auto(self, grey: np.ndarray) -> np.ndarray | None:
        """``auto``: this frame's motion when it moved and so did ``min_fraction`` of the
        window. A still camera is found cheaply: a frame is estimated only when its
        verdict can change a result. While fewer than ``min_fraction · window`` of the
        window's frames could have moved (those known to have moved, those not
        estimated, and this one), no motion is reported whatever this frame's verdict,
        and it is left unestimated; when a frame does move, the verdicts the window
        lacks are estimated then, from the grey images kept. Every reported motion, and
        every frame left without one, is that of estimating every frame (a still
        camera is estimated on about ``1 - min_fraction`` of its frames: a quarter)."""
        need = self.min_fraction * self.window
        self._greys = (self._greys + [grey])[-(self.window + 1):]
        past = self._recent[-(self.window - 1):] if self.window > 1 else []
        could = sum(v is not False for v in past) + 1
        if could < need:  # no verdict of this frame can make it reported
            self._recent = past + [None]
            return None
        A = self._estimate(self._greys[-2], grey)
        moved = self._moved(A)
        if moved:  # the window's unknown verdicts now decide: estimate them
            n = len(past)
            for k, v in enumerate(past):
                if v is None:
                    i = len(self._greys) - 1 - (n - k)  # that frame's grey
                    past[k] = self._moved(self._estimate(self._greys[i - 1], self._greys[i]))
        self._recent = past + [moved]
        if not moved or sum(v is True for v in self._recent) < need:
            return None
        self.frames_moved += 1
        return A

    @staticmethod
    def corner_shift(A: np.ndarray, width: int, height: int) -> float:
        """Largest displacement (px) of an image corner under the motion ``A``."""
        corners = np.array([[0, 0], [width, 0], [0, height], [width, height]], dtype=float)
        moved = corners @ A[:, :2].T + A[:, 2]
        return float(np.max(np.linalg.norm(moved - corners, axis=1)))
