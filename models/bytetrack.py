"""ByteTrack as a model config: SORT's graph with a second association round on low scores.

ByteTrack (Zhang et al. [#zhang2022]) is :mod:`pgm.models.sort`'s graph with another
:class:`~pgm.factors.association.DetectionAssociation`: the detections scoring at least
``high`` (0.6) are assigned first, then the *low-score* ones to the replicas left over —
so a person whose detector score drops under occlusion keeps being updated instead of
being lost — both rounds with an IoU gate of 0.1; only unmatched detections scoring at
least ``activation`` (0.7) start a track, confirmed after two matches *in a row*. The
defaults are the ``trackers`` package's (2.6.1).

>>> g = build_graph(Params())
>>> [r["min_score"] for r in g.factors["association"].rounds]
[0.6, -inf]

References
----------
.. [#zhang2022] Y. Zhang, P. Sun, Y. Jiang, D. Yu, F. Weng, Z. Yuan, P. Luo, W. Liu and
   X. Wang, "ByteTrack: multi-object tracking by associating every detection box",
   Proc. ECCV, 2022. doi:10.1007/978-3-031-20047-2_1
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

from pgm.core.graph import FactorGraph

from . import config as _config
from . import sort

__all__ = ["CONFIG", "Params", "build_graph", "rounds"]


def rounds(high: float = 0.6, iou: float = 0.1) -> tuple[dict[str, float], ...]:
    """ByteTrack's two association rounds: scores ≥ ``high``, then the rest."""
    return ({"iou": iou, "min_score": high}, {"iou": iou, "max_score": high})


@dataclass(frozen=True)
class Params(sort.Params):
    """:class:`pgm.models.sort.Params` with ByteTrack's defaults (two matches in a row to
    confirm, two rounds with an IoU gate of 0.1, activation 0.7)."""

    min_hits: int = 2
    consecutive: bool = True
    rounds: tuple[dict[str, float], ...] = field(default_factory=rounds)
    activation: float = 0.7


def build_graph(params: Params | None = None, name: str = "bytetrack") -> FactorGraph:
    """SORT's graph with ByteTrack's settings."""
    return sort.build_graph(params or Params(), name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "bytetrack", "multi-target", sys.modules[__name__],
    "ByteTrack: SORT with a second association round on low-score detections (Zhang et "
    "al. 2022)", options=sort.OPTIONS, build=sort.video_build)
