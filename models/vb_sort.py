"""VB-SORT: SORT with Feng et al.'s (2015) variational-Bayes measurement noise per target.

:mod:`pgm.models.sort`'s graph with, in the plate, an inverse-Gamma ``noise`` variable per
target (:class:`~pgm.factors.multitarget.InverseGammaPrior`, a
:class:`~pgm.factors.multitarget.NoiseForgetting` transition) and the conjugate
:class:`~pgm.factors.multitarget.VBNoise` factor on the assigned detection's likelihood:
each frame the engine runs the mean-field fixed point of ``q(x) q(R)`` for every matched
target (the VB adaptive Kalman filter of Särkkä & Nummenmaa that Feng et al. build their
VB-PHD on), so each target learns how far its detections scatter.

The noise is scale-aware (``noise="scale"``: stds in units of the box's width and height,
BoT-SORT's values; the belief is of the variance in those units). With the ``trackers``
package's pixel noise (``Q = 0.01``, ``R = 0.1``) learning ``R`` hurts: the learned
detection scatter (several px²) against a process noise that small makes the filter lag
behind walking people (``benchmarks/classic_trackers.py --variants``: ``sort --vb-noise``
loses up to 0.08 MOTA), because SORT's tiny ``R`` is what keeps its gain high. Learning
``R`` is sound only against a process noise of the right size. The noise is forgotten
slowly (ρ = 0.99): a detector's scatter is steady over a track's life.

>>> g = build_graph(Params())
>>> sorted(g.variables), g.factors["vb"].kind
(['box', 'noise'], 'conjugate')
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from pgm.core.graph import FactorGraph

from . import config as _config
from . import sort

__all__ = ["CONFIG", "Params", "build_graph"]


@dataclass(frozen=True)
class Params(sort.Params):
    """:class:`pgm.models.sort.Params` with ``vb_noise`` on and scale-aware noise."""

    noise: str = "scale"
    vb_noise: bool = True


def build_graph(params: Params | None = None, name: str = "vb-sort") -> FactorGraph:
    """SORT's graph with the VB noise factor."""
    return sort.build_graph(params or Params(), name=name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "vb-sort", "multi-target", sys.modules[__name__],
    "SORT with variational-Bayes measurement noise per target (Feng et al.'s (2015) VB on SORT)",
    options=tuple(o for o in sort.OPTIONS if o.dest != "vb_noise"), build=sort.video_build)
