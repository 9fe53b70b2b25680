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

from dataclasses import dataclass

import numpy as np

from pgm.appearance.likelihoods import ColourHistogramLikelihood
from pgm.factors import AR2Transition, GaussianPrior
from pgm.graph import FactorGraph
from pgm.numerics import check_finite_param
from pgm.variable import Variable

__all__ = ["Params", "build_graph", "BOX_LABELS"]

BOX_LABELS = ("cx", "cy", "w", "h")


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
    """

    init_box: tuple[float, float, float, float]
    num_particles: int = 100
    damping: float = 0.5
    pos_noise: float | None = None
    scale_noise: float = 0.0
    lam: float = 20.0
    layout: str = "perez"
    kernel: str = "uniform"


def build_graph(params: Params, name: str = "object") -> FactorGraph:
    """Build the one-node graph ``prior → object ← AR(2)``, ``object — colour — z``."""
    box = np.asarray(params.init_box, dtype=float)
    if box.shape != (4,):
        raise ValueError(f"init_box must be (cx, cy, w, h), got {params.init_box!r}")
    check_finite_param("init_box", box)
    if box[2] <= 0 or box[3] <= 0:
        raise ValueError(f"init_box must have positive width and height, got {params.init_box!r}")
    pos = params.pos_noise if params.pos_noise is not None else 0.03 * np.sqrt(box[2] * box[3])
    check_finite_param("pos_noise", pos, nonneg=True)
    transition = AR2Transition(
        name, noise_std=[pos, pos, 0.0, 0.0], damping=params.damping,
        scale_noise=params.scale_noise,
        reference_size=box[2:] if params.scale_noise > 0 else None)
    return FactorGraph(
        [Variable(name, 4, role="part", labels=BOX_LABELS)],
        [GaussianPrior(name, mean=box, cov=0.0),
         transition,
         ColourHistogramLikelihood(name, lam=params.lam, layout=params.layout,
                                   kernel=params.kernel)],
        name="colour-pf",
        meta={"output": name, "engine": {"num_particles": int(params.num_particles)}},
    )
