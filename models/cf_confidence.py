"""The single-object models' calibrated confidence: the logistic that turns the correlation
filter's peak-to-sidelobe ratio and the posterior's spread into ``P(IoU >= 0.5)``
(:func:`pgm.core.readout.confidence`), declared on a graph's correlation filter.

It sits below :mod:`pgm.models.part_graph` (whose re-detection reads it) and
:mod:`pgm.models.single_object` (which ships it), so neither imports the other.
"""

from __future__ import annotations

from pgm.core.graph import FactorGraph
from pgm.core.readout import check_confidence_spec
from pgm.observation.appearance.correlation import CorrelationFilterLikelihood

__all__ = ["CONFIDENCE", "with_confidence"]

#: logistic of the log peak-to-sidelobe ratio of the correlation filter's response map and the
#: log posterior spread, fitted on the eight single-object sequences (FaceOcc1, Crossing,
#: David, Tiger1, Girl, Biker, MotorRolling, UAV10-group3: its frames annotated absent count
#: as misses) and six PETS09-S2L1 person tracks, seeds 0-1, each of the nine videos weighted
#: equally (``python benchmarks/confidence.py --seeds 2``, which prints the
#: leave-one-group-out figures: held-out ECE per video 0.110 on average, 0.083 on the four
#: sequences added last against 0.143 for the earlier fit on the first four)
CONFIDENCE = {"intercept": -13.653, "slope": 5.790, "spread_slope": -0.160}


def with_confidence(graph: FactorGraph) -> FactorGraph:
    """``graph`` with the calibrated confidence (:data:`CONFIDENCE`) declared on its first
    correlation filter, where it has one and declares no confidence yet (in place)."""
    if "confidence" in graph.meta:
        return graph
    cf = [f for v in graph.variables for f in graph.factors_of(v, "likelihood")
          if isinstance(f, CorrelationFilterLikelihood)]
    if cf:
        graph.meta["confidence"] = check_confidence_spec(
            {"factor": cf[0].name, **CONFIDENCE}, graph.factors)
    return graph
