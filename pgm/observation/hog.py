"""OpenCV's HOG people detector (Dalal & Triggs 2005) as a detection source, its scores
calibrated as probabilities: ``pgm track VIDEO --detector hog``.

OpenCV ships the detector's linear SVM (trained on INRIA person windows: no download), but
only in the builds that have ``cv2.HOGDescriptor``: ``opencv-contrib-python(-headless)``
from version 5 on, every build before it. Where the installed OpenCV has none,
:class:`HOGPeopleDetector` is a one-line :class:`~pgm.core.errors.InputError` naming the
fix, and a detector of one's own (``--detector FILE.py:FUNCTION``) remains.

What it does per frame:

* the frame is resized so that a person :data:`SMALLEST` of its height tall fills the
  SVM's 128-pixel window (smaller people are not looked for; a frame of any size costs
  about the same);
* ``detectMultiScale`` (8-pixel stride, a 1.05 scale pyramid, the SVM's own threshold 0)
  gives windows and their SVM margins;
* a window holds the person with the INRIA training windows' margin, 16 of 128 pixels
  above and below and 16 of 64 on each side: the box reported is the window less that
  margin;
* overlapping boxes (IoU above :data:`NMS_IOU`) are suppressed, the highest margin kept;
* a margin ``m`` becomes the probability that the box is a person,
  ``1 / (1 + exp(-(a m + b)))`` (:data:`PLATT`: Platt's calibration, fitted on the
  shared MOT sequences; ``python benchmarks/detectors.py --hog`` prints its
  leave-one-sequence-out reliability).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from pgm.core.errors import InputError

from .detection_base import Detections, DetectionSource

__all__ = ["HOGPeopleDetector", "hog_available", "PLATT", "SMALLEST", "NMS_IOU"]

#: the smallest person looked for, as a share of the frame's height
SMALLEST = 1.0 / 6.0
#: boxes overlapping more than this (IoU) are one detection
NMS_IOU = 0.5
#: Platt's calibration of the SVM margin: ``P(person) = 1 / (1 + exp(-(a m + b)))``,
#: fitted on the detections of PETS09-S2L1, TUD-Campus, TUD-Stadtmitte and MOT16-11 matched
#: one to one to a person (IoU >= 0.5); held out one sequence at a time the fit moves little
#: (a 1.77-2.88, b -1.04 to -1.71) and the held-out expected calibration error is 0.03-0.09
#: (``python benchmarks/detectors.py --hog``)
PLATT = {"a": 2.264, "b": -1.327}
#: the SVM's window (pixels) and the INRIA training margin around the person in it
WINDOW = (64, 128)
MARGIN = (16, 16)


def hog_available() -> bool:
    """Whether the installed OpenCV has the HOG people detector."""
    return hasattr(cv2, "HOGDescriptor") and hasattr(cv2, "HOGDescriptor_getDefaultPeopleDetector")


class HOGPeopleDetector(DetectionSource):
    """OpenCV's HOG + linear SVM people detector, scores calibrated as probabilities (see
    the module docstring).

    Parameters
    ----------
    smallest : float
        The smallest person looked for, as a share of the frame's height.
    nms_iou : float
        Overlap (IoU) above which two boxes are one detection.
    platt : dict
        ``{"a": ..., "b": ...}``: the margin's calibration (default :data:`PLATT`).
    """

    name = "hog"
    #: the scale of the scores: probabilities
    score_range = np.array([0.0, 1.0])

    def __init__(self, *, smallest: float = SMALLEST, nms_iou: float = NMS_IOU,
                 platt: dict | None = None):
        if not hog_available():
            raise InputError(
                "--detector hog needs OpenCV's HOG people detector (cv2.HOGDescriptor), "
                f"which this OpenCV ({cv2.__version__}) does not have: install "
                "opencv-contrib-python-headless in place of opencv-python-headless, or give "
                "a detector of your own (--detector FILE.py:FUNCTION)")
        if not (math.isfinite(smallest) and 0 < smallest <= 1):
            raise InputError(f"hog: smallest must be a share of the frame's height in (0, 1], "
                             f"got {smallest!r}")
        if not (math.isfinite(nms_iou) and 0 < nms_iou <= 1):
            raise InputError(f"hog: nms_iou must be in (0, 1], got {nms_iou!r}")
        self.smallest, self.nms_iou = float(smallest), float(nms_iou)
        self.platt = dict(PLATT if platt is None else platt)
        self._hog = cv2.HOGDescriptor()
        self._hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())

    def margins(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The person boxes (top-left ``x, y, w, h`` in the frame's pixels, the training
        margin removed, overlaps suppressed) and their SVM margins."""
        h_img = image.shape[0]
        s = WINDOW[1] / (self.smallest * h_img)
        interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
        small = cv2.resize(image, None, fx=s, fy=s, interpolation=interp)
        rects, weights = self._hog.detectMultiScale(small, hitThreshold=0.0, winStride=(8, 8),
                                                    padding=(8, 8), scale=1.05)
        rects = np.asarray(rects, dtype=float).reshape(-1, 4) / s
        margin = np.asarray(weights, dtype=float).reshape(-1)
        if len(rects) == 0:
            return np.zeros((0, 4)), np.zeros(0)
        mx, my = MARGIN[0] / WINDOW[0], MARGIN[1] / WINDOW[1]
        boxes = np.stack([rects[:, 0] + mx * rects[:, 2], rects[:, 1] + my * rects[:, 3],
                          (1 - 2 * mx) * rects[:, 2], (1 - 2 * my) * rects[:, 3]], axis=1)
        keep = cv2.dnn.NMSBoxes(boxes.tolist(), np.maximum(margin, 0.0).tolist(), 0.0,
                                self.nms_iou)
        keep = np.asarray(keep, dtype=int).reshape(-1)
        return boxes[keep], margin[keep]

    def probability(self, margin: np.ndarray) -> np.ndarray:
        """The calibrated probability of each margin."""
        z = self.platt["a"] * np.asarray(margin, dtype=float) + self.platt["b"]
        return 1.0 / (1.0 + np.exp(-z))

    def __call__(self, frame_number: int, image: np.ndarray | None) -> Detections:
        if image is None:
            raise InputError(f"hog, frame {frame_number}: it needs the frame's image")
        boxes, margin = self.margins(image)
        return Detections(boxes, self.probability(margin))
