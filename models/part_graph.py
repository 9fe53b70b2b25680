"""Part graphs: two- and three-node trackers that survive partial occlusion [#zhang2015].

The object is split into parts — equal horizontal bands of the initial box by default
(two halves of a person, three bands of a face), vertical bands with
``split="cols"``, or explicit part boxes. Each part is a ``part`` variable with its
own point-mass prior, damped AR(2) transition and colour-histogram likelihood (the
template cut from that part's initial box); neighbouring parts are joined by a
coupling factor (a chain by default, all pairs with ``topology="full"``). Particle BP
(:mod:`pgm.inference.pbp`) passes message particles along the couplings, so a hidden
part is carried by its visible neighbours. The object's box is the mean of the boxes
that each part implies through its initial offset.

With ``n_parts=1`` this *is* the colour particle filter of Pérez et al. [#perez2002]
(:func:`pgm.models.colour_pf.build_graph` calls this function).

Defaults (:data:`DEFAULTS`): two bands, 100 particles per node and per message, an
online correlation filter per node (``"cf"``), a log-scale step and heavy-tailed jumps —
the settings that work across the four shared single-object sequences, chosen
leave-one-sequence-out (``python benchmarks/part_graph_defaults.py --seeds 2``: three of
the four folds pick them; success AUC FaceOcc1 0.893, Crossing 0.752, David 0.442,
Tiger1 0.681, against 0.803 / 0.254 / 0.273 / 0.127 at the paper's setting). One node
keeps the colour particle filter at 30 particles (:data:`ONE_NODE`).

The paper's setting (Zhang & Kang [#zhang2015]: 15 particles per node and per message for
two nodes, 10 and 10 for three, 30 for the one-node baseline; one colour histogram per
node, fixed size) is the preset ``"paper"`` (:data:`PRESETS`, :meth:`Params.paper`,
``pgm track --model part-graph --preset paper``): three bands unless ``n_parts`` says
otherwise. It keeps the toolkit's damped AR(2) (``damping=0.5``; the paper's is undamped),
as the previous defaults did.

>>> from pgm.models import part_graph
>>> g = part_graph.build_graph(part_graph.Params(init_box=(100, 80, 60, 90), n_parts=3))
>>> [v for v in g.variables], [f.name for f in g.factors_by_kind("coupling")]
(['top', 'middle', 'bottom'], ['coupling:top-middle', 'coupling:middle-bottom'])
>>> g.meta["engine"]["num_particles"], type(g.factors_of("top", "likelihood")[0]).__name__
(100, 'CorrelationFilterLikelihood')
>>> p = part_graph.Params.paper((100, 80, 60, 90))
>>> p.n_parts, p.num_particles, p.appearance
(3, 10, 'colour')

References
----------
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.core.numerics import check_finite_param
from pgm.core.readout import Targets, cxcywh_target, register_readout
from pgm.core.variable import Variable
from pgm.factors import AR2Transition, GaussianPrior
from pgm.factors.couplings import AffineCoupling, RelativeBoxCoupling
from pgm.inference.settings import EngineSettings
from pgm.observation.appearance.correlation import MAX_WINDOWS
from pgm.observation.appearance.cues import appearance_cues, cue_factor
from pgm.observation.appearance.redetection import RedetectionProposal

from . import config as _config
from .cf_confidence import CONFIDENCE

__all__ = ["CONFIG", "Params", "RedetectionAndAngle", "build_graph", "split_box", "part_names",
           "BOX_LABELS", "PAPER_PARTICLES", "DEFAULTS", "ONE_NODE", "PRESETS", "object_box"]

BOX_LABELS = ("cx", "cy", "w", "h")
#: particles per node (and per message) in the experiments of Zhang & Kang [#zhang2015]
PAPER_PARTICLES = {1: 30, 2: 15, 3: 10}
#: what the fields left at ``None`` take in a graph of two or more parts: chosen
#: leave-one-sequence-out over FaceOcc1, Crossing, David and Tiger1 among 2 or 3 parts,
#: the paper's / 50 / 100 particles, colour / cf / contrast+template, fixed size or a
#: log-scale step with jumps (``python benchmarks/part_graph_defaults.py --seeds 2``; the
#: same cue and motion as :mod:`pgm.models.single_object`, chosen again here)
DEFAULTS = {"num_particles": 100, "appearance": "cf", "scale_noise": 0.005, "jump_prob": 0.4}
#: what they take in a one-node graph: the colour particle filter of Pérez et al.
#: [#perez2002] at the paper's 30 particles (as before the defaults above were chosen)
ONE_NODE = {"num_particles": PAPER_PARTICLES[1], "appearance": "colour", "scale_noise": 0.0,
            "jump_prob": 0.0}
#: named settings (:meth:`Params.preset`, ``--preset NAME``); a dict value maps the node
#: count to the value. ``"paper"``: Zhang & Kang [#zhang2015] — three bands, 30/15/10
#: particles per node and per message for 1/2/3 nodes, one colour histogram, fixed size
PRESETS = {
    "paper": {"n_parts": 3, "num_particles": PAPER_PARTICLES, "appearance": "colour",
              "scale_noise": 0.0, "jump_prob": 0.0},
}


@dataclass(frozen=True, kw_only=True)
class RedetectionAndAngle:
    """Re-detection and an in-plane angle (one node with a correlation filter): the
    fields :class:`Params` and :class:`pgm.models.single_object.Params` share.

    Attributes
    ----------
    redetect : float
        One node with a correlation filter only: the share of particles a
        :class:`~pgm.observation.appearance.redetection.RedetectionProposal` draws near
        the response peaks of the frame around the estimate (``scan_side`` object
        sizes of the filter) in a frame where the calibrated confidence
        (``graph.meta["confidence"]``, where declared) is below one half (0: off, the
        default). Needs ``frame_size``; the transition's density then holds a
        re-appearance anywhere in the frame with probability ``reappear_prob`` per
        frame, which the proposal's importance weights carry and the transition does not
        draw (``AR2Transition(reappear_drawn=False)``).
    redetect_below, redetect_patience, redetect_false_alarm, redetect_min_response
        The proposal's ``below``, ``patience``, ``false_alarm`` and ``min_response``
        (:class:`~pgm.observation.appearance.redetection.RedetectionProposal`;
        ``redetect_false_alarm`` per frame at the reference rate, converted as
        ``reappear_prob`` is). A peak is proposed where it stands out of the scan's own
        noise at the false-alarm rate (1e-7 per frame); ``redetect_min_response`` 0 (the
        default) asks nothing of its response, None asks it to reach the filter's
        learning gate. Chosen on the eight single-object sequences (six seeds,
        ``docs/results.md``): a person blurred by a drone's pan still stands out of the
        map (6 to 8.5 standard deviations) at under half the filter's typical peak, and
        a rate of 1e-3 with no response test took a man's shirt for his face (David).
    reappear_prob : float
        See :class:`~pgm.factors.AR2Transition` (used with ``redetect`` only): a
        probability per frame at the reference rate, given to the video's frames as
        ``1 − (1 − p)^τ`` (``frame_step``), the same chance per *second*.
    rotation_noise : float
        One node with a correlation filter only: an in-plane angle (radians) as a fifth
        state component ``angle``, with this standard deviation per frame, which the
        filter sees (``angle_index``; 0: no angle, the default).
    frame_size : (width, height), optional
        The video's frame size in pixels (the application passes it).
    frame_step : float
        How many frames of the rate the per-frame noise constants are read at pass
        between two of the video's (``τ``; :mod:`pgm.models.single_object` sets it to
        30 frames/s over the video's declared rate; 1, the default: no conversion).
        The position, scale and angle noise per frame are multiplied by ``√τ``: the
        step of a random walk over ``τ`` reference frames, so that the motion allowed
        per *second* is the same at any frame rate.
    """

    redetect: float = 0.0
    redetect_below: float = 0.5
    redetect_patience: int = 1
    redetect_false_alarm: float = 1e-7
    redetect_min_response: float | None = 0.0
    reappear_prob: float = 0.01
    rotation_noise: float = 0.0
    frame_size: tuple[int, int] | None = None
    frame_step: float = 1.0


@dataclass(frozen=True)
class Params(RedetectionAndAngle):
    """Settings of a part graph.

    Attributes
    ----------
    init_box : (cx, cy, w, h)
        The object's box in the first frame (0-based pixels).
    n_parts : int
        1, 2 (default) or 3 equal bands (ignored when ``part_boxes`` is given).
    split : {"rows", "cols"}
        Horizontal bands (default; rows beat columns on FaceOcc1, AUC 0.815 against 0.764)
        or vertical.
    part_boxes : sequence of (cx, cy, w, h), optional
        Explicit part boxes instead of bands.
    topology : {"chain", "full"}
        Couplings between consecutive parts, or between all pairs.
    num_particles : int, optional
        Particles per node (default: 100 for two or more parts, 30 for one node; the
        paper's 30/15/10 for 1/2/3 parts: ``Params.paper``).
    message_particles : int, optional
        Message particles per coupling direction (default: one per node particle).
    fusion : {"mixture", "product"}
        Particle-BP fusion rule (:mod:`pgm.inference.pbp`).
    message_weight : {"source", "target"}
        Mixture message weights: the source's likelihood (eq. 26 of [#zhang2015]) or the
        target's (eq. 20).
    coupling : {"affine", "relative"}
        Fixed-offset affine map (default) or relative geometry.
    jitter : bool
        Position jitter on mixture message particles (std = the coupling's position σ).
    coupling_pos_std, coupling_size_std : float, optional
        σ of the coupling potential (product fusion): default position
        ``0.03 sqrt(w0 h0)`` px and size ``0.02 ×`` the part's size (results barely move
        across a 10× range).
    adapt_offsets : bool
        Let offsets adapt (forgetting ``offset_forgetting``) on frames where both parts
        score ``ρ ≥ adapt_min_rho`` at their estimates.
    damping, pos_noise, lam, layout, kernel
        As in :class:`pgm.models.colour_pf.Params`; the position noise default is
        ``0.03 sqrt(w0 h0)`` of the *object* box (parts move with the object).
    scale_noise : float, optional
        Std of a log-scale step per node and frame (default: 0.005 for two or more
        parts, 0 — fixed size — for one node); pair it with a cue that sees scale.
    appearance : str, optional
        Each node's likelihood factors: cues from
        :data:`pgm.observation.appearance.cues.CUES` joined by ``+``, which multiply
        (default: ``"cf"`` for two or more parts, ``"colour"`` for one node).
        ``"colour"``: one colour histogram of the box [#perez2002];
        ``"fragments"``: a grid of colour fragments combined by their median
        (:class:`~pgm.observation.appearance.likelihoods.FragmentsLikelihood`); ``"gradient"``: an
        oriented-gradient factor (:class:`~pgm.observation.appearance.likelihoods.GradientLikelihood`,
        λ/2), a cue that can see scale (pair it with ``scale_noise > 0``); ``"gmm"``:
        GMM-KL (:class:`~pgm.observation.appearance.likelihoods.GMMKLLikelihood`); ``"rings"``: the
        rotation-invariant model
        (:class:`~pgm.observation.appearance.likelihoods.RotationInvariantLikelihood`);
        ``"contrast"``: foreground/background colour log-odds
        (:class:`~pgm.observation.appearance.likelihoods.ColourContrastLikelihood`); ``"template"``:
        grey-level NCC template matching
        (:class:`~pgm.observation.appearance.likelihoods.TemplateLikelihood`, sees scale);
        ``"cf"``: an online-learned correlation filter's response map
        (:class:`~pgm.observation.appearance.correlation.CorrelationFilterLikelihood`,
        discriminative, sees scale). E.g. ``"contrast+template"``.
    jump_prob, jump_scale : float
        Heavy-tailed position step (see :class:`~pgm.factors.AR2Transition`): a fraction
        ``jump_prob`` of the particles moves with ``jump_scale`` × the position noise
        (default ``jump_prob``: 0.4 for two or more parts, 0 for one node).
    redetect, redetect_below, redetect_patience, redetect_false_alarm, redetect_min_response,
    reappear_prob,
    rotation_noise, frame_size
        Re-detection and an in-plane angle for one node with a correlation filter
        (:class:`RedetectionAndAngle`; keyword only).

    Fields left at ``None`` take :data:`DEFAULTS` (two or more parts) or :data:`ONE_NODE`
    (one node) when the graph is built (:meth:`resolved`).
    """

    init_box: tuple[float, float, float, float]
    n_parts: int = 2
    split: str = "rows"
    part_boxes: tuple | None = None
    topology: str = "chain"
    num_particles: int | None = None
    message_particles: int | None = None
    fusion: str = "mixture"
    message_weight: str = "source"
    coupling: str = "affine"
    jitter: bool = False
    coupling_pos_std: float | None = None
    coupling_size_std: float | None = None
    adapt_offsets: bool = False
    offset_forgetting: float = 0.95
    adapt_min_rho: float = 0.8
    damping: float = 0.5
    pos_noise: float | None = None
    scale_noise: float | None = None
    jump_prob: float | None = None
    jump_scale: float = 10.0
    lam: float = 20.0
    layout: str = "perez"
    kernel: str = "uniform"
    appearance: str | None = None

    @property
    def node_count(self) -> int:
        """The number of part nodes: the explicit part boxes', else ``n_parts``."""
        if self.part_boxes is not None:
            return int(np.asarray(self.part_boxes, dtype=float).size // 4)
        return int(self.n_parts)

    def resolved(self) -> Params:
        """These settings with every field left at ``None`` among :data:`DEFAULTS`' set:
        to :data:`DEFAULTS` for two or more parts, to :data:`ONE_NODE` for one node.

        >>> Params((50, 50, 20, 40)).resolved().appearance
        'cf'
        >>> Params((50, 50, 20, 40), n_parts=1).resolved().num_particles
        30
        """
        base = ONE_NODE if self.node_count == 1 else DEFAULTS
        fill = {k: v for k, v in base.items() if getattr(self, k) is None}
        return dataclasses.replace(self, **fill) if fill else self

    @classmethod
    def preset(cls, name: str, init_box, **fields) -> Params:
        """The named settings :data:`PRESETS` ``[name]`` for ``init_box``, ``fields`` on top
        (a node-count-dependent value is taken at the resulting node count).

        >>> p = Params.preset("paper", (50, 50, 20, 40), n_parts=2)
        >>> p.n_parts, p.num_particles, p.appearance, p.scale_noise
        (2, 15, 'colour', 0.0)
        """
        if name not in PRESETS:
            raise ValueError(f"unknown preset {name!r} (known: {', '.join(PRESETS)})")
        kwargs = {k: v for k, v in PRESETS[name].items() if not isinstance(v, dict)} | fields
        params = cls(init_box=init_box, **kwargs)
        n = params.node_count
        by_count = {k: v.get(n, min(v.values())) for k, v in PRESETS[name].items()
                    if isinstance(v, dict) and fields.get(k) is None}
        return dataclasses.replace(params, **by_count) if by_count else params

    @classmethod
    def paper(cls, init_box, **fields) -> Params:
        """The paper's setting (Zhang & Kang [#zhang2015]; ``PRESETS["paper"]``): three
        bands of 10 particles per node and message (two of 15, one of 30), one colour
        histogram per node, fixed size; ``fields`` on top."""
        return cls.preset("paper", init_box, **fields)


def part_names(n: int, split: str = "rows") -> list[str]:
    """Readable names of ``n`` bands."""
    names = {("rows", 1): ["object"], ("rows", 2): ["top", "bottom"],
             ("rows", 3): ["top", "middle", "bottom"], ("cols", 1): ["object"],
             ("cols", 2): ["left", "right"], ("cols", 3): ["left", "centre", "right"]}
    return names.get((split, n), [f"part{k}" for k in range(n)])


def split_box(box, n: int, split: str = "rows") -> np.ndarray:
    """``n`` equal, non-overlapping bands ``(n, 4)`` of a ``(cx, cy, w, h)`` box."""
    cx, cy, w, h = (float(v) for v in box)
    k = np.arange(n) + 0.5
    if split == "rows":
        return np.stack([np.full(n, cx), cy - h / 2 + k * h / n, np.full(n, w),
                         np.full(n, h / n)], axis=1)
    if split == "cols":
        return np.stack([cx - w / 2 + k * w / n, np.full(n, cy), np.full(n, w / n),
                         np.full(n, h)], axis=1)
    raise ValueError(f"split must be 'rows' or 'cols', got {split!r}")


def _check(params: Params) -> np.ndarray:
    box = np.asarray(params.init_box, dtype=float)
    if box.shape != (4,):
        raise ValueError(f"init_box must be (cx, cy, w, h), got {params.init_box!r}")
    check_finite_param("init_box", box)
    if box[2] <= 0 or box[3] <= 0:
        raise ValueError(f"init_box must have positive width and height, got {params.init_box!r}")
    if params.topology not in ("chain", "full"):
        raise ValueError(f"topology must be 'chain' or 'full', got {params.topology!r}")
    if params.coupling not in ("affine", "relative"):
        raise ValueError(f"coupling must be 'affine' or 'relative', got {params.coupling!r}")
    appearance_cues(params.appearance)
    if params.fusion not in ("mixture", "product"):
        raise ValueError(f"fusion must be 'mixture' or 'product', got {params.fusion!r}")
    if params.message_weight not in ("source", "target"):
        raise ValueError(f"message_weight must be 'source' or 'target', got "
                         f"{params.message_weight!r}")
    check_finite_param("redetect", params.redetect, nonneg=True)
    if params.redetect > 1:
        raise ValueError(f"redetect must be a share in [0, 1], got {params.redetect!r}")
    if params.frame_size is not None:
        fs = np.asarray(params.frame_size, dtype=float)
        if fs.shape != (2,) or not np.all(np.isfinite(fs)) or np.any(fs <= 0):
            raise ValueError(f"frame_size must be (width, height) > 0, got "
                             f"{params.frame_size!r}")
    for name in ("num_particles", "message_particles"):
        v = getattr(params, name)
        if v is not None and (isinstance(v, bool) or int(v) != v or v < 1):
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    return box


def has_cf(appearance: str) -> bool:
    """Whether the correlation filter (``"cf"``) is among the cues of ``appearance``: what
    re-detection and an in-plane angle need."""
    return any(cue == "cf" for cue, _ in appearance_cues(appearance))


def build_graph(params: Params, name: str = "part-graph") -> FactorGraph:
    """Build the part graph of ``params`` (one node: the colour particle filter); fields
    left at ``None`` take their defaults (:meth:`Params.resolved`)."""
    params = params.resolved()
    box = _check(params)
    if params.part_boxes is not None:
        parts = np.asarray(params.part_boxes, dtype=float).reshape(-1, 4)
        check_finite_param("part_boxes", parts)
        if np.any(parts[:, 2:] <= 0):
            raise ValueError("part_boxes must have positive widths and heights")
        names = [f"part{k}" for k in range(len(parts))]
    else:
        if params.n_parts not in (1, 2, 3) and params.n_parts < 1:
            raise ValueError(f"n_parts must be a positive integer, got {params.n_parts!r}")
        parts = split_box(box, int(params.n_parts), params.split)
        names = part_names(int(params.n_parts), params.split)
    n = len(parts)
    pos = params.pos_noise if params.pos_noise is not None else 0.03 * np.sqrt(box[2] * box[3])
    check_finite_param("pos_noise", pos, nonneg=True)
    step = float(check_finite_param("frame_step", params.frame_step, positive=True))
    walk = np.sqrt(step)  # a random walk's step over `frame_step` reference frames

    def per_step(p: float) -> float:  # a chance per reference frame, over `frame_step` of them
        # (as given at the reference rate, and where it is no probability: the factor says so)
        return p if step == 1.0 or not 0.0 <= p <= 1.0 else float(1.0 - (1.0 - p) ** step)
    pos = pos * walk
    c_pos = (params.coupling_pos_std if params.coupling_pos_std is not None
             else 0.03 * np.sqrt(box[2] * box[3]))
    variables, factors = [], []
    cues = appearance_cues(params.appearance)
    one_cf = n == 1 and has_cf(params.appearance)
    check_finite_param("rotation_noise", params.rotation_noise, nonneg=True)
    redetect, rotate = params.redetect > 0, params.rotation_noise > 0
    for option, on in (("redetect", redetect), ("rotation_noise", rotate)):
        if on and not one_cf:
            raise ValueError(f"{option} needs one node with the correlation filter ('cf') "
                             f"among its cues")
    if redetect and params.frame_size is None:
        raise ValueError("redetect needs frame_size=(width, height): the area a lost object "
                         "may re-appear in")
    region = (None if not redetect else
              (-0.5, -0.5, params.frame_size[0] - 0.5, params.frame_size[1] - 0.5))
    for nm, pb in zip(names, parts, strict=True):
        variables.append(Variable(nm, 5, role="part", labels=BOX_LABELS + ("angle",))
                         if rotate else Variable(nm, 4, role="part", labels=BOX_LABELS))
        factors += [
            GaussianPrior(nm, mean=[*pb, 0.0] if rotate else pb, cov=0.0),
            AR2Transition(nm, noise_std=[pos, pos, 0.0, 0.0] + ([params.rotation_noise * walk]
                                                                if rotate else []),
                          damping=params.damping,
                          scale_noise=params.scale_noise * walk,
                          reference_size=pb[2:] if params.scale_noise > 0 else None,
                          jump_prob=params.jump_prob, jump_scale=params.jump_scale,
                          reappear_prob=per_step(params.reappear_prob) if redetect else 0.0,
                          region=region, reappear_drawn=not redetect),
        ]
        for k, (cue, opts) in enumerate(cues):
            if redetect and cue == "cf":  # proposed particles read in windows of their own
                opts = {"windows": MAX_WINDOWS, **opts}
            if rotate and cue == "cf":  # the filter sees the angle
                opts = {"angle_index": 4, **opts}
            factors.append(cue_factor(cue, nm, params, name=None if k == 0 else f"{cue}:{nm}",
                                      options=opts))
            if cue == "cf":
                cf_name = factors[-1].name
        if redetect:
            factors.append(RedetectionProposal(nm, cue=cf_name, fraction=params.redetect,
                                                 below=params.redetect_below,
                                                 patience=params.redetect_patience,
                                                 false_alarm=per_step(
                                                     params.redetect_false_alarm),
                                                 min_response=params.redetect_min_response))
    if params.topology == "chain":
        pairs = [(k, k + 1) for k in range(n - 1)]
    else:
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    for i, j in pairs:
        a, b = parts[i], parts[j]
        size_std = (params.coupling_size_std if params.coupling_size_std is not None
                    else 0.02 * float(np.mean(a[2:])))
        std = [c_pos, c_pos, size_std, size_std]
        jitter = [c_pos, c_pos, 0.0, 0.0] if params.jitter else 0.0
        if params.coupling == "affine":
            factors.append(AffineCoupling(
                names[i], names[j], offset=a - b, std=std, jitter_std=jitter,
                forgetting=params.offset_forgetting if params.adapt_offsets else None,
                adapt_min_log_lik=-params.lam * (1.0 - params.adapt_min_rho)))
        else:
            factors.append(RelativeBoxCoupling(
                names[i], names[j], rel_offset=(a[:2] - b[:2]) / b[2:], rel_size=a[2:] / b[2:],
                std=std, jitter_std=jitter))
    n_particles = params.num_particles
    engine = EngineSettings(num_particles=int(n_particles))
    if n > 1:
        engine = engine.replace(fusion=params.fusion, message_weight=params.message_weight,
                                message_particles=int(params.message_particles or n_particles))
    meta = {"output": names if n > 1 else names[0], "engine": engine.to_dict()}
    if redetect:  # the proposal is on while the calibrated confidence is low
        meta["confidence"] = {"factor": cf_name, **CONFIDENCE}
    if n > 1:
        meta["readout"] = "part-offsets"
        meta["part_offsets"] = {nm: (box - pb).tolist()
                                for nm, pb in zip(names, parts, strict=True)}
    return FactorGraph(variables, factors, name=name, meta=meta)


@register_readout("part-offsets")
def object_box(graph: FactorGraph, record) -> Targets:
    """The object box: the mean of the boxes its parts imply through their offsets
    ``graph.meta["part_offsets"][part]`` (object box − part box at the start)."""
    offsets = graph.meta.get("part_offsets", {})
    implied = [np.asarray(record.estimates[n], dtype=float)[:4]
               + np.asarray(offsets.get(n, np.zeros(4)), dtype=float) for n in graph.output]
    return cxcywh_target(np.mean(implied, axis=0))


def _build(config, values, video):
    """Without ``--preset``: the default build (the options' fields into ``Params``).
    With it: :meth:`Params.preset` with the options given, and ``--particles``, on top."""
    name = values.get("preset")
    if name is None:
        return _config.default_build(config, values, video)
    fields = {o.field: values[o.dest] for o in config.options
              if o.field is not None and _config.given(values.get(o.dest))}
    if video.particles is not None:
        fields["num_particles"] = int(video.particles)
    box = None if video.init_box is None else tuple(float(v) for v in video.init_box)
    return build_graph(Params.preset(name, box, **fields))


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "part-graph", "single-object", sys.modules[__name__],
    "two or three parts of one object passing message particles (Zhang & Kang 2015)",
    options=(_config.PARTS,
             _config.Option("--split", "split", choices=("rows", "cols"),
                            help="horizontal (rows) or vertical bands (default: the model's, "
                                 "rows)"),
             _config.Option("--topology", "topology", choices=("chain", "full"),
                            help="couplings between neighbours (chain) or all pairs "
                                 "(default: the model's, chain)"),
             _config.Option("--fusion", "fusion", choices=("mixture", "product"),
                            help="particle-BP fusion rule (default: the model's, mixture)"),
             _config.APPEARANCE, _config.SCALE_NOISE,
             _config.Option("--preset", None, choices=tuple(PRESETS),
                            help="named settings, the other options on top: paper (Zhang & "
                                 "Kang 2015: 3 parts of 10 particles per node and message, "
                                 "2 of 15; a colour histogram per node; fixed size) (default: "
                                 "none: 2 parts of 100 particles, the correlation filter, a "
                                 "log-scale step and jumps, chosen on the shared sequences)")),
    build=_build)
