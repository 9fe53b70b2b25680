"""OC-SORT, its filtered boxes, and a colour model per track (the multi-target default until
issue 33).

:mod:`pgm.models.ocsort`'s graph with two of the ideas this toolkit adds to the classic
cores, each one setting:

* ``report="estimate"`` — a matched track reports its Kalman posterior box (the filtered
  box, which averages the detector's jitter) instead of the raw detection;
* ``appearance="colour"`` — each track keeps a colour histogram (the toolkit's
  :class:`~pgm.observation.appearance.likelihoods.ColourHistogramLikelihood`) learned
  from the detections it is given, and the association adds its similarity to each
  detection (``exp(ρ − 1)``, weight 1) to the IoU and OC-SORT's momentum term, so that
  people who cross keep their identities.

It was chosen leave one sequence out among 40 variants of the SORT, ByteTrack and
OC-SORT cores (``python benchmarks/classic_trackers.py --choose``): every fold picks it,
and on every held-out sequence it is at or above the best of the ``trackers`` package's
SORT, ByteTrack and OC-SORT in MOTA and IDF1 (numbers in ``docs/results.md``). Its
thresholds read the detector's own numbers, so detections with probabilities for scores
lose half their boxes to OC-SORT's 0.6; with ``--scores learned`` or ``quantile`` they do
not, and the multi-target default is now ``vb-phd``, chosen over sequences and their
perturbations (``benchmarks/robustness.py``). It needs the frames (for the colour
models) and, where the camera moves, compensates its motion as ``pgm track`` does.

>>> g = build_graph(Params())
>>> g.factors["association"].appearance, g.plates[0].lifecycle.report
('colour', 'matched')
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from pgm.core.graph import FactorGraph

from . import config as _config
from . import ocsort, sort

__all__ = ["CONFIG", "Params", "build_graph"]


@dataclass(frozen=True)
class Params(ocsort.Params):
    """:class:`pgm.models.ocsort.Params` reporting the filtered boxes, with colour
    appearance in the association."""

    report: str = "estimate"
    appearance: str | None = "colour"
    appearance_weight: float = 1.0


def build_graph(params: Params | None = None, name: str = "ocsort-colour") -> FactorGraph:
    """OC-SORT's graph with the filtered boxes and colour appearance."""
    return sort.build_graph(params or Params(), name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "ocsort-colour", "multi-target", sys.modules[__name__],
    "OC-SORT reporting its filtered boxes, with a colour model per track in the "
    "association (the multi-target default until issue 33)",
    options=sort.OPTIONS, build=sort.video_build)
