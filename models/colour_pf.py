"""The conventional colour particle filter (Pérez et al. [#perez2002]) as a graph.

One ``part`` variable ``object = (cx, cy, w, h)`` with

* a point-mass prior on the initial box (all particles on it, zero velocity),
* a damped AR(2) transition (eq. (13) of [#zhang2015]) with position noise
  ``s_x = s_y = 0.03 sqrt(w0 h0)`` px and fixed size (``s_w = s_h = 0``) by default,
* a colour-histogram likelihood (Bhattacharyya, ``λ = 20``, ``"perez"`` bins) whose
  template is learned from the first frame.

Resampling is selective (ESS < N/2) — the engine's default.

>>> from pgm.models import colour_pf
>>> g = colour_pf.build_graph(colour_pf.Params(init_box=(100, 80, 40, 60)))
>>> sorted(f.kind for f in g.factors.values())
['likelihood', 'prior', 'transition']

References
----------
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass

from pgm.core.graph import FactorGraph

from . import config as _config
from .part_graph import BOX_LABELS

__all__ = ["CONFIG", "Params", "build_graph", "one_node_graph", "BOX_LABELS"]


@dataclass(frozen=True)
class Params:
    """Settings of the colour particle filter.

    Attributes
    ----------
    init_box : (cx, cy, w, h)
        The object's box in the first frame (centre convention, 0-based pixels).
    num_particles : int
        Default particle count stored in the graph (the baseline of [#zhang2015] uses 30).
    damping : float
        AR(2) damping ``a`` (1 = the model of [#zhang2015]; 0.5 default, which scored
        AUC 0.75 against 0.65 undamped on FaceOcc1).
    pos_noise : float, optional
        Position noise std in px (default ``0.03 sqrt(w0 h0)``).
    scale_noise : float
        Std of a shared log-scale step (0: fixed size, the default), clamped to
        [0.5, 2] × the initial size.
    jump_prob, jump_scale : float
        Heavy-tailed position step for fast motion: a fraction ``jump_prob`` of the
        particles moves with ``jump_scale`` times the position noise (0: none).
    lam : float
        Likelihood sharpness λ (20).
    layout : str
        ``"perez"`` (default), ``"hsv"`` or ``"rgb"``.
    kernel : str
        ``"uniform"`` (default) or ``"epanechnikov"``.
    appearance : str
        ``"colour"`` (the likelihood of [#perez2002], default) or other cues joined by ``+``
        (:data:`pgm.observation.appearance.cues.CUES`; see :class:`pgm.models.part_graph.Params`).
    """

    init_box: tuple[float, float, float, float]
    num_particles: int = 100
    damping: float = 0.5
    pos_noise: float | None = None
    scale_noise: float = 0.0
    jump_prob: float = 0.0
    jump_scale: float = 10.0
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
    """The one-node part graph of ``params`` (any ``Params`` with these fields; those a
    part graph has not, such as :class:`pgm.models.single_object.Params`'s ``fps``, are
    left to the caller)."""
    from . import part_graph

    known = {f.name for f in dataclasses.fields(part_graph.Params)}
    fields = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)
              if f.name in known}
    return part_graph.build_graph(part_graph.Params(n_parts=1, **fields), name=graph_name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "colour-pf", "single-object", sys.modules[__name__],
    "the colour particle filter of Pérez et al. (2002): one box, a colour histogram",
    options=(_config.APPEARANCE, _config.SCALE_NOISE))
