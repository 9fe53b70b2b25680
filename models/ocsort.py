"""OC-SORT as a model config: SORT's graph with observation-centric association and re-update.

OC-SORT (Cao et al. [#cao2023]) keeps SORT's Kalman box state (the paper's centre, area
and aspect) and changes what the detections do to it, each change a setting of
:mod:`pgm.models.sort`'s factors:

* **momentum** (OCM) — the association maximises IoU plus 0.2 × score × the agreement
  between a track's direction of motion over its last three detections and the direction
  to the candidate detection (:class:`~pgm.factors.association.DetectionAssociation`,
  ``"direction"``);
* **recovery** (OCR) — a second round matches the tracks left over by their *last
  detection* rather than their prediction (``"against": "last"``);
* **re-update** (ORU) — a track found again after a gap is re-filtered along virtual
  detections interpolated across the gap (``AssignedDetectionLikelihood(reupdate=True)``);

and its life cycle: only detections scoring at least 0.6 are used, every one left over
starts a track, tentative tracks are kept through misses, a track is reported after three
matches in a row after its first detection (three in a row also when found again), and in
the video's first frames at once. The
defaults are the ``trackers`` package's (2.6.1), which ``benchmarks/classic_trackers.py``
reproduces.

>>> g = build_graph(Params())
>>> [r["against"] for r in g.factors["association"].rounds]
['prediction', 'last']

References
----------
.. [#cao2023] J. Cao, J. Pang, X. Weng, R. Khirodkar and K. Kitani, "Observation-centric
   SORT: rethinking SORT for robust multi-object tracking", Proc. IEEE/CVF CVPR, 2023.
   doi:10.1109/CVPR52729.2023.00934
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

from pgm.core.graph import FactorGraph

from . import config as _config
from . import sort

__all__ = ["CONFIG", "Params", "build_graph", "rounds"]


def rounds(high: float = 0.6, iou: float = 0.3) -> tuple[dict, ...]:
    """OC-SORT's rounds: momentum-aided matching on predictions, then recovery on the last
    detections, both on the detections scoring at least ``high``."""
    return ({"iou": iou, "min_score": high, "direction": True},
            {"iou": iou, "min_score": high, "against": "last"})


@dataclass(frozen=True)
class Params(sort.Params):
    """:class:`pgm.models.sort.Params` with OC-SORT's settings."""

    box_state: str = "xysr"
    min_hits: int = 3
    consecutive: bool = True
    rounds: tuple[dict, ...] = field(default_factory=rounds)
    activation: float = 0.6
    recover_hits: int = 3
    keep_tentative: bool = True
    birth_counts: bool = False
    warmup: bool = True
    reupdate: bool = True


def build_graph(params: Params | None = None, name: str = "ocsort") -> FactorGraph:
    """SORT's graph with OC-SORT's settings."""
    return sort.build_graph(params or Params(), name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "ocsort", "multi-target", sys.modules[__name__],
    "OC-SORT: SORT with observation-centric momentum, recovery and re-update (Cao et al. "
    "2023)", options=sort.OPTIONS, build=sort.video_build)
