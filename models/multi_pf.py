"""One particle filter per person — or one part graph per person — as a plate.

The model of one person, declared once and replicated per target by the engine
(:class:`pgm.inference.Engine`, whose plate variables hold batched beliefs):

* one ``part`` variable ``person = (cx, cy, w, h)`` (``n_parts = 1``), or 2–3 horizontal
  bands coupled by scale-free :class:`~pgm.factors.couplings.RelativeBoxCoupling`
  factors (``n_parts = 2 | 3``: the part graph of :mod:`pgm.models.part_graph`, per
  person, so that a person half hidden keeps being tracked by the visible band);
* a damped AR(2) transition (damping 1 is the conventional tracker's constant velocity)
  whose noise is in units of each box's own height per √s
  (``AR2Transition(relative=True)``, scaled by the frame rate), so near and far people,
  and 7 and 30 frames/s, share one setting;
* appearance likelihoods learned from each person's birth frame (any
  ``--appearance`` cue string, copied per replica);
* :class:`~pgm.factors.plates.DetectionLikelihood`: the frame's detections, without
  deciding which is whose;
* :class:`~pgm.factors.plates.MutualExclusion` between the replicas;
* births and deaths from detections: the plate's :class:`~pgm.core.plate.Lifecycle`.

>>> g = build_graph(Params())
>>> g.plates[0].variables
('person',)
>>> sorted({f.kind for f in g.factors.values()})
['interaction', 'likelihood', 'prior', 'transition']
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.core.numerics import check_finite_param
from pgm.core.plate import Lifecycle, Plate
from pgm.core.variable import Variable
from pgm.factors import AR2Transition, GaussianPrior
from pgm.factors.couplings import RelativeBoxCoupling
from pgm.factors.plates import DetectionLikelihood, MutualExclusion
from pgm.inference.settings import EngineSettings
from pgm.observation.appearance.cues import appearance_cues, cue_factor

from . import config as _config
from .part_graph import BOX_LABELS, split_box

__all__ = ["CONFIG", "Params", "build_graph", "person_graph", "evidence_factors", "REFERENCE_BOX"]

#: the box the declaration is written for (a person 100 px tall); replicas are placed
#: relative to it
REFERENCE_BOX = (100.0, 100.0, 40.0, 100.0)


@dataclass(frozen=True)
class Params:
    """Settings of the per-person trackers.

    Attributes
    ----------
    num_particles : int
        Particles per person (per part).
    n_parts : int
        1 (one box per person), 2 or 3 (horizontal bands).
    appearance : str
        Appearance cues per node joined by ``+`` (:data:`pgm.observation.appearance.cues.CUES`).
    lam, layout, kernel :
        Colour-likelihood settings, as in :class:`pgm.models.part_graph.Params`.
    fps : float
        The video's frame rate: the noise below is per square-root second (Brownian), so
        its per-frame std is ``noise / sqrt(fps)`` — one setting for 7 and 30 frames/s.
    pos_noise : float
        Std of the position step in box heights per √s.
    scale_noise : float
        Std of the shared log-scale step per √s.
    damping : float
        AR(2) damping (1: constant velocity).
    detection_pos_std, detection_size_std, detection_strength : float
        :class:`~pgm.factors.plates.DetectionLikelihood` settings (0 strength: no
        detection term, appearance only).
    exclusion : float
        :class:`~pgm.factors.plates.MutualExclusion` strength (0: none).

        The detection strength (2000), the exclusion (10) and the lifecycle's
        ``max_coast`` (0) were chosen leave one sequence out over the four shared MOT
        sequences (``benchmarks/plate_trackers.py --choose``: a 3 × 2 × 3 grid; the
        choice on all four, and of two of the four folds).
    lifecycle : Lifecycle
        Births and deaths.
    """

    num_particles: int = 100
    n_parts: int = 1
    appearance: str = "colour"
    lam: float = 20.0
    layout: str = "perez"
    kernel: str = "uniform"
    fps: float = 25.0
    pos_noise: float = 0.185
    scale_noise: float = 0.05
    damping: float = 0.5
    detection_pos_std: float = 0.05
    detection_size_std: float = 0.1
    detection_strength: float = 2000.0
    exclusion: float = 10.0
    lifecycle: Lifecycle = field(default_factory=Lifecycle)


def _check(p: Params) -> None:
    if isinstance(p.num_particles, bool) or int(p.num_particles) != p.num_particles or \
            p.num_particles < 1:
        raise ValueError(f"num_particles must be a positive integer, got {p.num_particles!r}")
    if p.n_parts not in (1, 2, 3):
        raise ValueError(f"n_parts must be 1, 2 or 3, got {p.n_parts!r}")
    appearance_cues(p.appearance)
    for name in ("pos_noise", "scale_noise", "detection_strength", "exclusion"):
        check_finite_param(name, getattr(p, name), nonneg=True)
    for name in ("detection_pos_std", "detection_size_std"):
        check_finite_param(name, getattr(p, name), positive=True)
    check_finite_param("fps", p.fps, positive=True)
    check_finite_param("damping", p.damping)
    if not 0.0 <= p.damping <= 1.0:
        raise ValueError(f"damping must be in [0, 1], got {p.damping!r}")


def evidence_factors(nm: str, p, extent=(0.0, 0.0, 1.0, 1.0)) -> list:
    """A person node's evidence: its appearance cues (``p.appearance``), the frame's
    detections (``extent``: where the node's box lies in the person's) and mutual
    exclusion with the other replicas — as ``p`` (any Params with those fields) sets them."""
    out = [cue_factor(cue, nm, p, name=None if j == 0 else f"{cue}:{nm}", options=opts)
           for j, (cue, opts) in enumerate(appearance_cues(p.appearance))]
    if p.detection_strength > 0:
        out.append(DetectionLikelihood(nm, pos_std=p.detection_pos_std,
                                       size_std=p.detection_size_std,
                                       strength=p.detection_strength, extent=extent,
                                       name=f"detections:{nm}"))
    if p.exclusion > 0:
        out.append(MutualExclusion(nm, strength=p.exclusion, name=f"exclusion:{nm}"))
    return out


def person_graph(p: Params, name: str) -> tuple[list, list, list[str]]:
    """Variables, factors and output names of one person (the plate's contents)."""
    box = np.asarray(REFERENCE_BOX)
    n = int(p.n_parts)
    names = ["person"] if n == 1 else [f"part{k}" for k in range(n)]
    parts = box[None] if n == 1 else split_box(box, n, "rows")
    variables, factors = [], []
    per_frame = 1.0 / np.sqrt(p.fps)
    pos, scale = p.pos_noise * per_frame, p.scale_noise * per_frame
    for k, (nm, pb) in enumerate(zip(names, parts, strict=True)):
        variables.append(Variable(nm, 4, role="part", labels=BOX_LABELS))
        factors += [
            GaussianPrior(nm, mean=pb, cov=0.0),
            AR2Transition(nm, noise_std=[pos, pos, 0.0, 0.0], damping=p.damping,
                          scale_noise=scale, relative=True),
        ]
        factors += evidence_factors(nm, p, extent=(0.0, k / n, 1.0, (k + 1) / n))
    for k in range(n - 1):
        a, b = parts[k], parts[k + 1]
        factors.append(RelativeBoxCoupling(
            names[k], names[k + 1], rel_offset=(a[:2] - b[:2]) / b[2:], rel_size=a[2:] / b[2:]))
    return variables, factors, names


def build_graph(params: Params | None = None, name: str = "multi-pf") -> FactorGraph:
    """The plate graph of ``params``: one person's sub-graph, replicated per target."""
    p = params or Params()
    _check(p)
    variables, factors, names = person_graph(p, name)
    engine = EngineSettings(num_particles=int(p.num_particles))
    meta = {"output": names if len(names) > 1 else names[0], "engine": engine.to_dict(),
            "readout": "plate", "reference_box": list(REFERENCE_BOX)}
    plate = Plate("person", tuple(names), lifecycle=p.lifecycle)
    return FactorGraph(variables, factors, name=name, meta=meta, plates=[plate])


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "multi-pf", "multi-target", sys.modules[__name__],
    "one particle filter (or part graph) per person, as a plate",
    options=(_config.PARTS, _config.APPEARANCE, _config.SCALE_NOISE))
