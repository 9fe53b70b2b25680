"""The toolkit's best single-object configuration: what ``pgm track SOURCE --init ...``
runs when no ``--model`` is given.

One ``object`` node (the colour particle filter's graph, damped AR(2), fixed size,
100 particles) whose likelihood multiplies three cues, declared and nothing more:

* fragments — a 3×3 grid of colour histograms combined by their median, so a partly
  occluded object still scores on its visible part;
* rings — the rotation-invariant ring model of seed 003 §3.2.7: per-ring colour means
  and variances, which see the object's spatial colour layout;
* contrast — foreground/background colour log-odds summed over the box, which punishes
  boxes that drift onto background.

Chosen by the ablation of ``benchmarks/appearance_eval.py`` on the two single-object
sequences of ``../shared/data`` (FaceOcc1 and Crossing), the only ones there are: it was
the best configuration across both, so these figures are not held-out figures. A
person track of the MOT sequences, run as a single-object task, is the held-out check
the same script prints.

>>> from pgm.models import single_object
>>> g = single_object.build_graph(single_object.Params(init_box=(100, 80, 40, 60)))
>>> [type(f).__name__ for f in g.factors_of("object", "likelihood")]
['FragmentsLikelihood', 'RotationInvariantLikelihood', 'ColourContrastLikelihood']
"""

from __future__ import annotations

from dataclasses import dataclass

from pgm.graph import FactorGraph

__all__ = ["Params", "build_graph", "APPEARANCE"]

APPEARANCE = "fragments+rings+contrast"


@dataclass(frozen=True)
class Params:
    """Settings; the fields are those of :class:`pgm.models.colour_pf.Params` with the
    defaults of the best configuration (``appearance``, 100 particles)."""

    init_box: tuple[float, float, float, float]
    num_particles: int = 100
    damping: float = 0.5
    pos_noise: float | None = None
    scale_noise: float = 0.0
    lam: float = 20.0
    layout: str = "perez"
    kernel: str = "uniform"
    appearance: str = APPEARANCE


def build_graph(params: Params, name: str = "object") -> FactorGraph:
    """The one-node part graph with the three cues (:func:`pgm.models.part_graph.build_graph`)."""
    from . import part_graph

    if name != "object":
        raise ValueError("the single-object model's variable is called 'object'")
    return part_graph.build_graph(
        part_graph.Params(init_box=params.init_box, n_parts=1,
                          num_particles=params.num_particles, damping=params.damping,
                          pos_noise=params.pos_noise, scale_noise=params.scale_noise,
                          lam=params.lam, layout=params.layout, kernel=params.kernel,
                          appearance=params.appearance),
        name="single-object")
