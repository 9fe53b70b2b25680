"""The toolkit's best single-object configuration: what ``pgm track SOURCE --init ...``
runs when no ``--model`` is given.

One ``object`` node (the colour particle filter's graph: damped AR(2) on the centre,
100 particles) with a shared log-scale step (``SCALE_NOISE`` per frame, clamped to
[0.5, 2] × the first box) and a likelihood that multiplies two cues, declared
and nothing more:

* contrast — foreground/background colour log-odds summed over the box, which punishes
  boxes that drift onto background or shrink inside the object;
* template — grey-level normalised cross-correlation on a grid of points placed
  relative to the box, which sees the object's structure and so its scale.

Chosen by the ablation of ``benchmarks/appearance_eval.py`` on the two single-object
sequences of ``../shared/data`` (FaceOcc1 and Crossing), the only ones there are: it was
the best configuration across both, so these figures are not held-out figures. A
person track of the MOT sequences, run as a single-object task, is the held-out check
the same script prints.

>>> from pgm.models import single_object
>>> g = single_object.build_graph(single_object.Params(init_box=(100, 80, 40, 60)))
>>> [type(f).__name__ for f in g.factors_of("object", "likelihood")]
['ColourContrastLikelihood', 'TemplateLikelihood']
"""

from __future__ import annotations

from dataclasses import dataclass

from pgm.core.graph import FactorGraph

from . import colour_pf

__all__ = ["Params", "build_graph", "APPEARANCE", "SCALE_NOISE"]

APPEARANCE = "contrast+template"
SCALE_NOISE = 0.005


@dataclass(frozen=True)
class Params(colour_pf.Params):
    """The fields of :class:`pgm.models.colour_pf.Params` (100 particles by default)
    with the best configuration's ``appearance`` and ``scale_noise``."""

    appearance: str = APPEARANCE
    scale_noise: float = SCALE_NOISE


def build_graph(params: Params, name: str = "object") -> FactorGraph:
    """The one-node part graph with the two cues (:func:`pgm.models.part_graph.build_graph`)."""
    if name != "object":
        raise ValueError("the single-object model's variable is called 'object'")
    return colour_pf.one_node_graph(params, "single-object")
