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

from . import colour_pf

__all__ = ["Params", "build_graph", "APPEARANCE"]

APPEARANCE = "fragments+rings+contrast"


@dataclass(frozen=True)
class Params(colour_pf.Params):
    """The fields of :class:`pgm.models.colour_pf.Params` (100 particles by default)
    with the best configuration's ``appearance``."""

    appearance: str = APPEARANCE


def build_graph(params: Params, name: str = "object") -> FactorGraph:
    """The one-node part graph with the three cues (:func:`pgm.models.part_graph.build_graph`)."""
    if name != "object":
        raise ValueError("the single-object model's variable is called 'object'")
    return colour_pf.one_node_graph(params, "single-object")
