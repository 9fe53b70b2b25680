"""C-BIoU as a model config: BoT-SORT's rounds on the buffered IoU, without camera motion.

C-BIoU (Yang et al. [#yang2023]) keeps the cascade of rounds of ByteTrack and BoT-SORT
(:mod:`pgm.models.botsort`) and changes what a pair is scored by: the IoU of the two
boxes each enlarged about its centre to ``(1 + 2b) w × (1 + 2b) h`` — the *buffered*
IoU, so that a person whose motion the Kalman prediction misses (a turn, a stop, a
jump of the detector's box) still overlaps its detection. The cascade buffers a little
first and more later: ``b = 0.3`` in the confident detections' rounds (confirmed tracks,
then tentative ones; IoU × score as BoT-SORT), ``b = 0.5`` in the low scores' round of
the tracks matched in the previous frame (a round's ``"buffer"``,
:class:`~pgm.factors.association.DetectionAssociation`). The Kalman state and the life
cycle are BoT-SORT's (scale-aware noise, confirmed at the second match, the first
frame's tracks at once); there is no camera-motion compensation (``camera_warp="none"``:
a frame's image motion, if any, is not used). The defaults are the ``trackers``
package's (2.6.1), which ``tests/test_peers.py`` reproduces.

>>> g = build_graph(Params())
>>> [r["buffer"] for r in g.factors["association"].rounds]
[0.3, 0.5, 0.3]

References
----------
.. [#yang2023] F. Yang, S. Odashima, S. Masui and S. Jiang, "Hard to track objects with
   irregular motions and similar appearances? Make it easier by buffering the matching
   space", Proc. IEEE/CVF WACV, 2023. arXiv:2211.14317
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

from pgm.core.graph import FactorGraph

from . import botsort, sort
from . import config as _config

__all__ = ["CONFIG", "Params", "build_graph", "rounds"]


def rounds(high: float = 0.6, low: float = 0.1, buffer: float = 0.3,
           low_buffer: float = 0.5) -> tuple[dict, ...]:
    """C-BIoU's rounds: BoT-SORT's, buffered by ``buffer`` (``b1``: the confident
    detections' rounds) and ``low_buffer`` (``b2``: the low scores')."""
    return botsort.rounds(high=high, low=low, buffer=buffer, low_buffer=low_buffer)


@dataclass(frozen=True)
class Params(botsort.Params):
    """:class:`pgm.models.botsort.Params` with C-BIoU's rounds and no camera motion."""

    rounds: tuple[dict, ...] = field(default_factory=rounds)
    camera_warp: str = "none"
    camera_order: str = "before"


def build_graph(params: Params | None = None, name: str = "cbiou") -> FactorGraph:
    """SORT's graph with C-BIoU's settings."""
    return botsort.build_graph(params or Params(), name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "cbiou", "multi-target", sys.modules[__name__],
    "C-BIoU: BoT-SORT's cascade of rounds on the buffered IoU, no camera motion (Yang et al. "
    "2023)", options=sort.OPTIONS, build=sort.video_build)
