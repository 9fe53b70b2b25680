"""The conventional colour particle filter (Pérez et al. 2002; SPEC §1) as a graph.

One ``part`` variable ``object = (cx, cy, w, h)`` with

* a point-mass prior on the initial box (all particles on it, zero velocity),
* a damped AR(2) transition (seed 002, eq. 13) with position noise
  ``s_x = s_y = 0.03 sqrt(w0 h0)`` px and fixed size (``s_w = s_h = 0``) by default,
* a colour-histogram likelihood (Bhattacharyya, ``λ = 20``, ``"perez"`` bins) whose
  template is learned from the first frame.

Resampling is selective (ESS < N/2) — the engine's default.

>>> from pgm.models import colour_pf
>>> g = colour_pf.build_graph(colour_pf.Params(init_box=(100, 80, 40, 60)))
>>> sorted(f.kind for f in g.factors.values())
['likelihood', 'prior', 'transition']
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from pgm.core.graph import FactorGraph

from .part_graph import BOX_LABELS

__all__ = ["Params", "build_graph", "one_node_graph", "BOX_LABELS"]


@dataclass(frozen=True)
class Params:
    """Settings of the colour particle filter.

    Attributes
    ----------
    init_box : (cx, cy, w, h)
        The object's box in the first frame (centre convention, 0-based pixels).
    num_particles : int
        Default particle count stored in the graph (the paper's baseline uses 30).
    damping : float
        AR(2) damping ``a`` (1 = the paper's model; 0.5 default, SPEC §1).
    pos_noise : float, optional
        Position noise std in px (default ``0.03 sqrt(w0 h0)``).
    scale_noise : float
        Std of a shared log-scale step (0: fixed size, the default), clamped to
        [0.5, 2] × the initial size.
    lam : float
        Likelihood sharpness λ (20).
    layout : str
        ``"perez"`` (default), ``"hsv"`` or ``"rgb"``.
    kernel : str
        ``"uniform"`` (default) or ``"epanechnikov"``.
    appearance : str
        ``"colour"`` (SPEC §1, default) or other cues joined by ``+``
        (:data:`pgm.models.part_graph.CUES`; see :class:`pgm.models.part_graph.Params`).
    """

    init_box: tuple[float, float, float, float]
    num_particles: int = 100
    damping: float = 0.5
    pos_noise: float | None = None
    scale_noise: float = 0.0
    lam: float = 20.0
    layout: str = "perez"
    kernel: str = "uniform"
    appearance: str = "colour"


def build_graph(params: Params, name: str = "object") -> FactorGraph:
    """Build the one-node graph ``prior → object ← AR(2)``, ``object — colour — z``.

    This is the one-node case of :func:`pgm.models.part_graph.build_graph`, not a
    separate code path.
    """
    if name != "object":
        raise ValueError("the colour PF's variable is called 'object'")
    return one_node_graph(params, "colour-pf")


def one_node_graph(params: Params, graph_name: str) -> FactorGraph:
    """The one-node part graph of ``params`` (any ``Params`` with these fields)."""
    from . import part_graph

    fields = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
    return part_graph.build_graph(part_graph.Params(n_parts=1, **fields), name=graph_name)
