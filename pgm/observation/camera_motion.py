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

Frames are analysed at most ``max_side`` pixels wide (the motion is rescaled to full
resolution). ``mode="auto"`` attaches a frame's motion only when the camera is
*moving*: the frame's fit moves some image corner by more than ``min_shift`` pixels
(default 1 px), and so did at least ``min_fraction`` (80 %) of the last ``window`` (20)
frames' fits. A still camera's estimates stay below 1 px (median corner shift 0.06–0.13
px on Crossing, PETS09-S2L1, TUD-Campus, TUD-Stadtmitte and Tiger1); a large object
crossing a still camera (FaceOcc1's face and magazine) can pass the per-frame tests
for a few frames, not for 16 of 20: 12 of FaceOcc1's 888 frames are compensated, none
of those five sequences' or of the synthetic scenes', against 282 of MOT16-11's 300
(a moving camera) and 222 of David's 462 (a panning camera). The runners turn it on
(``"auto"``) for multi-target models and leave it off for one object, whose camera
usually follows it (see :func:`pgm.app.runner.track`).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["CameraMotionEstimator", "estimate_camera_motion", "MODES"]

MODES = ("auto", "on", "off")


def _grey(image: np.ndarray, scale: float) -> np.ndarray:
    img = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if scale != 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    return img


def estimate_camera_motion(prev_grey: np.ndarray, grey: np.ndarray, *, max_corners: int = 400,
                           ransac_threshold: float = 1.0, min_coverage: float = 0.5
                           ) -> tuple[np.ndarray | None, int]:
    """Similarity ``[M | t]`` ``(2, 3)`` taking ``prev_grey`` pixels to ``grey``, and the
    number of RANSAC inliers.

    ``None, 0`` when the image motion is not the camera's: too few corners followed; a
    fit whose inliers do not span ``min_coverage`` of the image's width and height (a
    moving object, not the background); or a fit that explains fewer corners than
    "nothing moved" does (a still camera watching people walk).
    """
    pts = cv2.goodFeaturesToTrack(prev_grey, maxCorners=max_corners, qualityLevel=0.01,
                                  minDistance=8, blockSize=7)
    if pts is None or len(pts) < 8:
        return None, 0
    nxt, status, _ = cv2.calcOpticalFlowPyrLK(prev_grey, grey, pts, None, winSize=(21, 21),
                                              maxLevel=3)
    ok = status.reshape(-1) == 1
    if ok.sum() < 8:
        return None, 0
    p0, p1 = pts[ok].reshape(-1, 2), nxt[ok].reshape(-1, 2)
    A, inliers = cv2.estimateAffinePartial2D(p0, p1, method=cv2.RANSAC,
                                             ransacReprojThreshold=ransac_threshold,
                                             maxIters=2000, confidence=0.995)
    if A is None or inliers is None or not np.all(np.isfinite(A)):
        return None, 0
    inl = inliers.reshape(-1).astype(bool)
    n = int(inl.sum())
    n_still = int(np.count_nonzero(np.linalg.norm(p1 - p0, axis=1) < ransac_threshold))
    h, w = prev_grey.shape[:2]
    span = np.ptp(p0[inl], axis=0) if n else np.zeros(2)
    if n < 8 or n <= n_still or span[0] < min_coverage * w or span[1] < min_coverage * h:
        return None, 0
    return A.astype(float), n


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
        Frames are analysed at most this many pixels wide.
    """

    def __init__(self, mode: str = "auto", *, min_shift: float = 1.0, window: int = 20,
                 min_fraction: float = 0.8, max_side: int = 640):
        if mode not in MODES:
            raise ValueError(f"camera motion mode must be one of {MODES}, got {mode!r}")
        if not np.isfinite(min_shift) or min_shift < 0:
            raise ValueError(f"min_shift must be a non-negative number, got {min_shift!r}")
        if int(window) < 1 or not 0.0 <= float(min_fraction) <= 1.0:
            raise ValueError(f"need window >= 1 and min_fraction in [0, 1], got {window!r}, "
                             f"{min_fraction!r}")
        self.mode, self.min_shift, self.max_side = mode, float(min_shift), int(max_side)
        self.window, self.min_fraction = int(window), float(min_fraction)
        self._recent: list[bool] = []
        self._prev: np.ndarray | None = None
        self._scale = 1.0
        self._size: tuple[int, int] | None = None
        #: frames whose motion was reported (``auto``: found significant)
        self.frames_moved = 0

    def __call__(self, image: np.ndarray) -> np.ndarray | None:
        """The motion from the previous image to ``image`` (``None`` for the first frame,
        when off, when not significant under ``auto``, or when it cannot be estimated)."""
        if self.mode == "off" or image is None:
            return None
        h, w = image.shape[:2]
        if self._size != (w, h):  # first frame (or a size change): start afresh
            self._size = (w, h)
            self._recent = []
            self._scale = min(1.0, self.max_side / max(w, h))
            self._prev = _grey(image, self._scale)
            return None
        grey = _grey(image, self._scale)
        A, _ = estimate_camera_motion(self._prev, grey)
        self._prev = grey
        if A is not None:
            A = A.copy()
            A[:, 2] /= self._scale  # translation back to full-resolution pixels
        if self.mode == "auto":
            moved = A is not None and self.corner_shift(A, w, h) >= self.min_shift
            self._recent = (self._recent + [moved])[-self.window:]
            if not moved or sum(self._recent) < self.min_fraction * self.window:
                return None
        if A is None:
            return None
        self.frames_moved += 1
        return A

    @staticmethod
    def corner_shift(A: np.ndarray, width: int, height: int) -> float:
        """Largest displacement (px) of an image corner under the motion ``A``."""
        corners = np.array([[0, 0], [width, 0], [0, height], [width, height]], dtype=float)
        moved = corners @ A[:, :2].T + A[:, 2]
        return float(np.max(np.linalg.norm(moved - corners, axis=1)))
