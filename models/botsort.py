"""BoT-SORT as a model config: SORT's graph with pooled rounds, score fusion and camera motion.

BoT-SORT (Aharon et al. [#aharon2022]) without its re-identification features is
:mod:`pgm.models.sort`'s graph with ByteTrack's cascade of rounds, each a setting of the
:class:`~pgm.factors.association.DetectionAssociation` (a round's ``"tracks"`` pool,
``"fuse_score"``), and three changes to the target's Kalman state:

* **rounds** — the confirmed tracks (lost ones included) against the detections scoring
  at least ``high`` (0.6), maximising IoU × score with the gate on that product (0.2);
  then the confirmed tracks matched in the previous frame and left over against the
  detections scoring in ``[low, high)`` (0.1, 0.6; the package's floor is strict, ``>
  0.1``), on IoU alone with a gate of 0.5; then the tentative tracks against the
  confident detections left, on IoU × score gated at 0.3;
* **scale-aware noise** — ``Q``, ``R`` and ``P0`` with stds in units of the box's width
  and height (1/20, 1/160, 1/20; ``P0`` = 2 and 10 times them: ``noise="scale"``). On the
  corner state this gives the means of the paper's centre-and-size filter exactly (each
  covariance is the paper's times ½ on the centre and 2 on the size, which no gain sees);
* **camera-motion compensation** — the frame's image motion moves the predicted box's
  centre and its rate, not its size, after the predict (``camera_warp="centre"``,
  ``camera_order="after"``; :class:`~pgm.factors.association.BoxTransition`). BoT-SORT
  estimates it on every frame by sparse optical flow (the ``trackers`` package's
  estimate is :class:`~pgm.observation.camera_motion.CameraMotionEstimator`
  ``("on", method="botsort")``); ``pgm track`` attaches the toolkit's own estimate,
  which is none on a still camera;

and its life cycle: tracks start on the unmatched detections scoring at least
``activation`` (0.7), are confirmed at their second match, end at their first miss while
tentative, are kept ``ceil(fps)`` frames without a match once confirmed (30 at 30
frames/s), and those born in the video's first frame are confirmed at once
(``activate_first``). The defaults are the ``trackers`` package's (2.6.1), which
``tests/test_peers.py`` reproduces.

>>> g = build_graph(Params())
>>> [r["tracks"] for r in g.factors["association"].rounds]
['confirmed', 'tracked', 'tentative']

References
----------
.. [#aharon2022] N. Aharon, R. Orfaig and B.-Z. Bobrovsky, "BoT-SORT: robust associations
   multi-pedestrian tracking", arXiv:2206.14651, 2022.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, replace

from pgm.core.graph import FactorGraph

from . import config as _config
from . import sort

__all__ = ["CONFIG", "Params", "build_graph", "rounds", "with_score_threshold"]


def rounds(high: float = 0.6, low: float = 0.1, iou: float = 0.2, low_iou: float = 0.5,
           tentative_iou: float = 0.3, buffer: float = 0.0, low_buffer: float = 0.0
           ) -> tuple[dict, ...]:
    """BoT-SORT's three rounds: confirmed tracks and confident detections (IoU × score),
    tracks matched last frame and the detections in ``[low, high)`` (IoU), tentative
    tracks and the confident detections left (IoU × score); ``buffer`` and
    ``low_buffer`` enlarge the boxes of the first and third, and of the second
    (C-BIoU's cascade, :mod:`pgm.models.cbiou`)."""
    first = {"iou": iou, "min_score": high, "tracks": "confirmed", "fuse_score": True}
    second = {"iou": low_iou, "min_score": low, "max_score": high, "tracks": "tracked"}
    third = {"iou": tentative_iou, "min_score": high, "tracks": "tentative", "fuse_score": True}
    if buffer:
        first["buffer"] = third["buffer"] = buffer
    if low_buffer:
        second["buffer"] = low_buffer
    return (first, second, third) if low < high else (first, third)


#: the split between confident and other detections set, bands' floors kept
#: (:func:`pgm.models.sort.with_score_threshold`)
with_score_threshold = sort.with_score_threshold


@dataclass(frozen=True)
class Params(sort.Params):
    """:class:`pgm.models.sort.Params` with BoT-SORT's settings."""

    noise: str = "scale"
    min_hits: int = 2
    rounds: tuple[dict, ...] = field(default_factory=rounds)
    activation: float = 0.7
    activate_first: bool = True
    camera_warp: str = "centre"
    camera_order: str = "after"


def build_graph(params: Params | None = None, name: str = "botsort") -> FactorGraph:
    """SORT's graph with BoT-SORT's settings (``score_threshold``: the confident
    detections' split and ``activation`` there, the low band's floor kept)."""
    p = params or Params()
    if p.score_threshold is not None:
        sort._check(p)  # the settings as given
        p = replace(p, rounds=with_score_threshold(p.rounds, p.score_threshold),
                    activation=float(p.score_threshold), score_threshold=None)
    return sort.build_graph(p, name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "botsort", "multi-target", sys.modules[__name__],
    "BoT-SORT: SORT with pooled rounds on IoU x score, scale-aware noise and camera-motion "
    "compensation (Aharon et al. 2022)", options=sort.OPTIONS, build=sort.video_build)
