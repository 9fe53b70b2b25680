"""SORT as a model config: a plate of exact Kalman box states, data association as a factor.

SORT (Bewley et al. [#bewley2016]) declared as a factor graph of the one engine. One
target is a ``state`` variable ``box`` — the four columns of a box code (the corners
``x1, y1, x2, y2`` by default, as the ``trackers`` package's SORT; ``box_state="xysr"``:
the paper's centre, area and aspect) and their rates — with

* :class:`~pgm.factors.association.BoxPrior` — ``N(detection, P0)``, rates zero;
* :class:`~pgm.factors.LinearGaussianTransition` — constant velocity, noise ``Q``;
* :class:`~pgm.factors.association.DetectionAssociation` — Hungarian on IoU with a gate
  (the ``assign`` stage: after predict, before the update);
* :class:`~pgm.factors.association.AssignedDetectionLikelihood` — ``z = H x + N(0, R)``
  on the assigned detection, the Kalman update;

replicated by the plate, whose :class:`~pgm.core.plate.Lifecycle` is SORT's: a replica
is born on every unmatched detection scoring at least ``activation``, confirmed at its
``min_hits``-th match, removed at its first miss while tentative, kept through
``lost_frames`` frames without a match once confirmed, and reported only in the frames
it is matched, with the detection's box. The engine keeps ``box`` as a
:class:`~pgm.core.batched.BatchedGaussian` (``EngineSettings.beliefs``), so a frame is
a few batched matrix products over all replicas (:mod:`pgm.inference.association`).

The defaults are those of the ``trackers`` package (2.6.1), which ``benchmarks/
classic_trackers.py`` reproduces: ``Q = 0.01 I``, ``R = 0.1 I``, ``P0 = I`` on the corner
state (the paper's state: ``R = diag(1, 1, 10, 10)``, ``P0 = 10 diag(1, 1, 1, 1, 1000,
1000, 1000)``, ``Q = diag(1, 1, 1, 1, 0.01, 0.01, 0.0001)``); a lost-track buffer of 30
frames at 30 frames/s (``ceil(fps)`` frames at the video's rate).

The papers' ideas are added as factors, one option each: ``vb_noise`` (Feng et al.'s (2015)
variational-Bayes measurement noise per target: an inverse-Gamma ``noise`` variable in
the plate and the conjugate :class:`~pgm.factors.multitarget.VBNoise` factor).

>>> g = build_graph(Params())
>>> sorted(f.kind for f in g.factors.values())
['association', 'likelihood', 'prior', 'transition']
>>> g.variables["box"].labels[:4]
('x1', 'y1', 'x2', 'y2')

References
----------
.. [#aharon2022] N. Aharon, R. Orfaig and B.-Z. Bobrovsky, "BoT-SORT: robust associations
   multi-pedestrian tracking", arXiv:2206.14651, 2022.
.. [#bewley2016] A. Bewley, Z. Ge, L. Ott, F. Ramos and B. Upcroft, "Simple online and
   realtime tracking", Proc. IEEE ICIP, 2016. doi:10.1109/ICIP.2016.7533003
"""

from __future__ import annotations

import math
import numbers
import sys
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pgm.core.boxes import encode_boxes
from pgm.core.graph import FactorGraph
from pgm.core.numerics import check_finite_param
from pgm.core.plate import EXPLAIN_TENTATIVE, Lifecycle, Plate
from pgm.core.variable import Variable
from pgm.factors.association import (
    LEARNED_SCORE_MAPS,
    SCORE_MAPS,
    AssignedDetectionLikelihood,
    BoxPrior,
    BoxTransition,
    DetectionAssociation,
    constant_velocity,
)
from pgm.factors.multitarget import InverseGammaPrior, NoiseForgetting, VBNoise
from pgm.factors.persistent_quantiles import PLACED_LEVEL
from pgm.inference.settings import EngineSettings

from . import config as _config
from .sort_time import at_frame_rate, lost_frames
from .sort_time import noise_diagonals as _noise

__all__ = ["CONFIG", "Params", "at_frame_rate", "build_graph", "lost_frames", "score_map_for",
           "video_build", "with_score_threshold",
           "OPTIONS", "appearance_factors"]

#: the box (cx, cy, w, h) the declaration's prior is written for; births re-centre it
REFERENCE_BOX = (100.0, 100.0, 40.0, 100.0)
#: the box codes a SORT state may use
BOX_STATES = ("xyxy", "xysr")
#: the noise models: fixed pixels (the trackers package) or in units of the box's size
NOISES = ("fixed", "scale")
#: the motion models: the exact Kalman filter, or particles moved by cv, cv3 or a GPDM
MOTIONS = ("kalman", "cv", "cv3", "gpdm")
#: what a matched track reports: its detection's box, or the Kalman posterior mean
REPORTS = ("detection", "estimate")
#: what the counts of matches count with a reference frame rate (:func:`at_frame_rate`)
HIT_COUNTS = ("seconds", "detections")
#: how the process noise converts with a reference frame rate (:func:`at_frame_rate`)
NOISE_PERS = ("second", "detection", "displacement")


@dataclass(frozen=True)
class Params:
    """Settings of SORT (and of ByteTrack, :mod:`pgm.models.bytetrack`).

    Attributes
    ----------
    box_state : {"xyxy", "xysr"}
        The box code of the state: corners (the ``trackers`` package) or centre, area,
        aspect (the SORT paper).
    motion : {"kalman", "cv", "cv3", "gpdm"}
        ``"kalman"``: the exact Kalman box state (the classic trackers). The others make
        the box state particles (``num_particles`` per target; centre and size, noise
        scale-aware) moved by a learned or averaged motion model in place of the constant
        velocity — Wang et al.'s (2008) idea on these cores: ``"cv"`` (constant velocity, the
        baseline), ``"cv3"`` (velocity averaged over three frames) or ``"gpdm"`` (the
        GPDM chain of ``gpdm``, a file written by ``pgm learn gpdm``), with the noise of
        :class:`pgm.models.gpdm.Params` (``pos_noise``, ``scale_noise`` per √s).
    gpdm : str, optional
        The GPDM file for ``motion="gpdm"``.
    num_particles : int
        Particles per target of the particle motions (100).
    process_noise, measurement_noise, initial_cov : sequence of float, optional
        Diagonals of ``Q``, ``R`` and ``P0`` (default: the code's, module docstring).
    noise : {"fixed", "scale"}
        ``"fixed"``: the diagonals above, in pixels; ``"scale"``: scale-aware noise, each
        std a fraction of the box's width or height along its axis (BoT-SORT's Kalman
        filter [#aharon2022]): ``pos_std`` for the box's coordinates, ``vel_std`` for their
        rates, ``meas_std`` for the detection, ``P0`` = (2 ``pos_std``, 10 ``vel_std``) —
        one setting for people near and far, at 480 or 1080 lines (corner or centre
        states only).
    pos_std, vel_std, meas_std : float
        The scale-aware stds (1/20, 1/160, 1/20: BoT-SORT's published values, not tuned
        here).
    initial_pos_std, initial_rate_std : float, optional
        The scale-aware initial stds of the box's coordinates and of their rates (default
        ``2 pos_std`` and ``10 vel_std``, BoT-SORT's).
    fps : float
        The video's frame rate (the lost-track buffer is in frames at 30 frames/s).
    reference_fps : float, optional
        Read the per-frame constants — ``min_hits``, ``recover_hits``, ``delta_t``, the
        process noise and the initial rate uncertainty — as their values at this frame
        rate, and convert them to the video's (:func:`at_frame_rate`), so that a 7 and a
        30 frames/s video get the same behaviour per second. None (the classic cores, as
        the ``trackers`` package): per frame of whatever rate the video has.
    lost_buffer : int
        Frames at 30 frames/s a confirmed track is kept without a match (30).
    min_hits : int
        Matches before a track is confirmed (3).
    consecutive : bool
        Confirm after ``min_hits`` matches in a row (ByteTrack) instead of in all.
    rounds : tuple of dict
        The association's rounds (:class:`~pgm.factors.association.DetectionAssociation`;
        SORT: one, IoU ≥ 0.3).
    activation : float
        Score a detection needs to start a track (0.25).
    score_map : str
        How scores reach [0, 1] before the thresholds (one of
        :data:`~pgm.factors.scores.SCORE_MAPS`). The package's cores read the
        detector's own numbers (:func:`score_map_for` picks ``"none"`` or ``"logistic"``
        for a video; ``"constant"`` when the detector's scores have no known scale);
        ``"learned"`` makes each score the probability that its detection is of a
        target, learned on the video (:class:`~pgm.factors.persistence.PersistenceScoreModel`),
        and ``"quantile"`` its quantile among the video's scores
        (:class:`~pgm.factors.scores.ScoreQuantiles`): both give the same tracks for any
        strictly increasing map of the scores, and every threshold below is then in
        their units.
    placed_level : float
        With ``score_map="placed"``, ``"placed-rebased"`` or ``"placed-over"``, the
        placement relative to the best-scored detections' at which a detection below the
        threshold is lifted to it
        (:data:`~pgm.factors.persistent_quantiles.PLACED_LEVEL`,
        :class:`~pgm.factors.persistent_quantiles.PersistentQuantiles`).
    gate_confidence : float, optional
        With a gated score map, the confidence with which the video must show detections
        to be clutter before they are cut (None: the point estimate alone).
    score_threshold : float, optional
        Set every score threshold — the rounds' split between confident and other
        detections and ``activation`` — to this value (:func:`with_score_threshold`;
        with ``"learned"``, a probability).
    recover_hits : int
        Matches in a row before a track found again after a miss is reported (1; OC-SORT:
        ``min_hits``).
    keep_tentative : bool
        Keep a tentative track through misses as long as a confirmed one (OC-SORT)
        instead of ending it at its first.
    birth_counts : bool
        Whether the detection that starts a track counts as its first match towards
        ``min_hits`` (SORT, ByteTrack) or not (OC-SORT: three matches after it).
    warmup : bool
        In the video's first ``min_hits + 1`` frames a matched track is confirmed at once
        (OC-SORT).
    direction_weight, delta_t : float, int
        The momentum term of rounds with ``"direction"`` (OC-SORT: 0.2, 3).
    reupdate : bool
        OC-SORT's observation-centric re-update of tracks found again.
    occlusion_gate : float, optional
        Zhang and Kang's (2015) part idea on the box (corner states): an edge of a detection lying
        inside the predicted box by more than this many σ is taken as hidden and does not
        update the target's box (:class:`~pgm.factors.association.AssignedDetectionLikelihood`).
    appearance : str, optional
        Appearance cues for association and re-identification (``"colour"``, ``"cf"``,
        ...): one model per track learned from its detections, its similarity with each
        detection added to the association's score with ``appearance_weight`` (the
        toolkit's appearance factors; :class:`~pgm.factors.association.DetectionAssociation`).
    appearance_weight : float
        Its weight against the IoU (0.5).
    report : {"detection", "estimate"}
        The box a matched track reports: its detection's (the ``trackers`` package) or the
        Kalman posterior mean (the filtered box); either way only in frames with a match.
    vb_noise : bool
        Feng et al.'s (2015) adaptive measurement noise per target (``vb-sort``).
    vb_rho, vb_alpha0 : float
        Its forgetting factor and prior shape (the prior's mean is ``R``). ``ρ = 0.99``: a
        detector's noise is a property of the detector, steady over a track's life (seed
        000's 0.8 forgets a shared noise that drifts; per track it makes each track's gain
        follow its last few residuals: PETS09-S2L1 IDF1 0.399 against 0.454).
    activate_first : bool
        The tracks born in the video's first frame are confirmed and reported at once
        (BoT-SORT, C-BIoU; :class:`~pgm.core.plate.Lifecycle` ``activate_first``).
    camera_warp : {"box", "centre", "none"}
        What the camera's image motion moves in the Kalman state: the whole box, its
        centre and the centre's rate only (BoT-SORT), or nothing (C-BIoU)
        (:class:`~pgm.factors.association.BoxTransition` ``camera``).
    camera_order : {"before", "after"}
        Whether the camera's motion is applied before the predict or after it (BoT-SORT).
    birth_iou : float
        No track is born on a detection whose IoU with a track's predicted box (or with
        another birth of the frame) exceeds this: a detection a track already explains —
        a detector's second box on a person, a box on part of one — starts no second
        identity, though it may still match a track (1: off, the package's cores).
    explain_tentative : {"none", "prediction", "detection"}
        The same rule for every match of a track not yet confirmed (a birth in
        progress): removed when its detection overlaps a confirmed track's predicted box
        (``"prediction"``), or a higher-scored detection a confirmed track was given
        (``"detection"``), by more than ``birth_iou``
        (:attr:`~pgm.core.plate.Lifecycle.explain_tentative`; ``"none"``: births only).
    fill_gaps : float
        Seconds: a track found again after at most this long without a match also
        reports the frames between, its box interpolated between the two it reported,
        written when it is found (:attr:`~pgm.core.plate.Lifecycle.fill_gaps`, in the
        video's frames; 0: never, the package's cores).
    fill_after : int, optional
        Matches in a row a track found again needs before its gap is filled, in frames at
        ``reference_fps`` like ``min_hits`` (None: ``min_hits``, the evidence a new
        track needs; :attr:`~pgm.core.plate.Lifecycle.fill_after`).
    fill_births : bool
        A track confirmed also reports the frames it was tentative in, with the boxes
        estimated then, written when it is confirmed
        (:attr:`~pgm.core.plate.Lifecycle.fill_births`).
    count_hits : {"seconds", "detections"}
        What ``min_hits``, ``recover_hits`` and ``fill_after`` count with a
        ``reference_fps``: frames at that rate, a window of time converted to the video's
        (``"seconds"``), or detections, the same at any rate (``"detections"``: the
        evidence that tells an object from clutter is a number of detections).
    noise_per : {"second", "detection", "displacement"}
        How the process noise converts with a ``reference_fps`` (:func:`at_frame_rate`):
        a continuous-time random walk (``"second"``: more noise between frames further
        apart), the same step each detection, only its rates put in the video's units
        (``"detection"``: the noise models the detections' irregularity in velocity, which
        does not grow with the time between them), or the same step in the video's pixels
        (``"displacement"``: the irregularity is a box's displacement from one detection to
        the next — a pose, a detector's jitter — which moves a rate in pixels per frame by
        as much at any frame rate; only the initial rate variance, a speed, converts).
    """

    box_state: str = "xyxy"
    motion: str = "kalman"
    gpdm: str | None = None
    num_particles: int = 100
    pos_noise: float = 0.185
    scale_noise: float = 0.05
    process_noise: tuple[float, ...] | None = None
    measurement_noise: tuple[float, ...] | None = None
    initial_cov: tuple[float, ...] | None = None
    noise: str = "fixed"
    pos_std: float = 1.0 / 20.0
    vel_std: float = 1.0 / 160.0
    meas_std: float = 1.0 / 20.0
    initial_pos_std: float | None = None
    initial_rate_std: float | None = None
    fps: float = 30.0
    reference_fps: float | None = None
    lost_buffer: int = 30
    min_hits: int = 3
    consecutive: bool = False
    rounds: tuple[dict[str, float], ...] = field(default_factory=lambda: ({"iou": 0.3},))
    activation: float = 0.25
    score_map: str = "none"
    placed_level: float = PLACED_LEVEL
    gate_confidence: float | None = None
    score_threshold: float | None = None
    recover_hits: int = 1
    keep_tentative: bool = False
    birth_counts: bool = True
    warmup: bool = False
    direction_weight: float = 0.2
    delta_t: int = 3
    reupdate: bool = False
    occlusion_gate: float | None = None
    appearance: str | None = None
    appearance_weight: float = 0.5
    report: str = "detection"
    vb_noise: bool = False
    vb_rho: float = 0.99
    vb_alpha0: float = 10.0
    activate_first: bool = False
    camera_warp: str = "box"
    camera_order: str = "before"
    birth_iou: float = 1.0
    explain_tentative: str = "none"
    fill_gaps: float = 0.0
    fill_after: int | None = None
    fill_births: bool = False
    count_hits: str = "seconds"
    noise_per: str = "second"


def appearance_factors(appearance: str | None) -> list | None:
    """The appearance factors of a cue string (``"colour"``, ``"fragments+gradient"``, ...;
    :mod:`pgm.observation.appearance.cues`) on a ``(cx, cy, w, h)`` box, with the
    toolkit's shared colour settings (λ 20, Pérez bins, uniform kernel); None for none."""
    if not appearance:
        return None
    from types import SimpleNamespace

    from pgm.observation.appearance.cues import appearance_cues, cue_factor

    shared = SimpleNamespace(lam=20.0, layout="perez", kernel="uniform")
    return [cue_factor(cue, "box", shared, name=f"appearance:{cue}:{k}", options=opts)
            for k, (cue, opts) in enumerate(appearance_cues(appearance))]


def score_map_for(scores: np.ndarray) -> str:
    """``"logistic"`` when any of a sequence's detection scores lies outside [0, 1] (a
    detector's margins or unbounded scores: MOT15's run to ~140, MOT16's DPM scores are
    negative too), else ``"none"`` — one monotone map per sequence, so the scores keep
    their order (the benchmark protocol of ``benchmarks/peers/mot_peers.py``)."""
    s = np.asarray(scores, dtype=float)
    return "logistic" if s.size and (s.min() < 0.0 or s.max() > 1.0) else "none"


def with_score_threshold(rounds, threshold: float) -> tuple[dict, ...]:
    """``rounds`` with the split between confident and other detections at ``threshold``
    (ByteTrack's confident and other detections split there; OC-SORT's rounds take the
    confident ones): a round on a band of scores (finite ``max_score``: ByteTrack's low
    round, BoT-SORT's ``[0.1, 0.6)``) ends there and keeps its floor (the round dropped
    when its floor is not below it), every other finite ``min_score`` is set to it."""
    t = float(threshold)
    out = []
    for r in rounds:
        r = dict(r)
        hi, lo = r.get("max_score"), r.get("min_score")
        if hi is not None and math.isfinite(float(hi)):
            r["max_score"] = t
            if lo is not None and float(lo) >= t:
                continue
        elif lo is not None and math.isfinite(float(lo)):
            r["min_score"] = t
        out.append(r)
    return tuple(out)


def _check(p: Params) -> None:
    if p.box_state not in BOX_STATES:
        raise ValueError(f"box_state must be one of {BOX_STATES}, got {p.box_state!r}")
    if p.motion not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {p.motion!r}")
    if p.motion == "gpdm" and not p.gpdm:
        raise ValueError("motion 'gpdm' needs a learned GPDM file (pgm learn gpdm; --gpdm FILE)")
    if isinstance(p.num_particles, bool) or int(p.num_particles) != p.num_particles or \
            p.num_particles < 1:
        raise ValueError(f"num_particles must be a positive integer, got {p.num_particles!r}")
    if p.noise not in NOISES:
        raise ValueError(f"noise must be one of {NOISES}, got {p.noise!r}")
    if p.noise == "scale" and p.box_state == "xysr":
        raise ValueError("scale-aware noise needs the corner state (box_state='xyxy')")
    if p.reference_fps is not None:
        check_finite_param("reference_fps", p.reference_fps, positive=True)
    for name in ("initial_pos_std", "initial_rate_std"):
        if getattr(p, name) is not None:
            check_finite_param(name, getattr(p, name), positive=True)
    for name in ("pos_std", "vel_std", "meas_std"):
        check_finite_param(name, getattr(p, name), positive=True)
    if p.report not in REPORTS:
        raise ValueError(f"report must be one of {REPORTS}, got {p.report!r}")
    if p.score_map not in SCORE_MAPS:
        raise ValueError(f"score_map must be one of {SCORE_MAPS}, got {p.score_map!r}")
    check_finite_param("fps", p.fps, positive=True)
    check_finite_param("activation", p.activation)
    check_finite_param("fill_gaps", p.fill_gaps)
    if p.fill_gaps < 0:
        raise ValueError(f"fill_gaps must be at least 0 seconds, got {p.fill_gaps}")
    if p.score_threshold is not None:
        check_finite_param("score_threshold", p.score_threshold)
        if p.score_map in LEARNED_SCORE_MAPS and not 0.0 <= p.score_threshold <= 1.0:
            raise ValueError(f"score_threshold is in [0, 1] with the {p.score_map} score map, "
                             f"got {p.score_threshold}")
    if p.noise_per not in NOISE_PERS:
        raise ValueError(f"noise_per must be one of {NOISE_PERS}, got {p.noise_per!r}")
    if p.count_hits not in HIT_COUNTS:
        raise ValueError(f"count_hits must be one of {HIT_COUNTS}, got {p.count_hits!r}")
    if p.fill_births not in (True, False):
        raise ValueError(f"fill_births must be a bool, got {p.fill_births!r}")
    for name in ("lost_buffer", "min_hits", "fill_after"):
        v = getattr(p, name)
        if v is None and name == "fill_after":
            continue
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or int(v) != v \
                or v < (0 if name == "lost_buffer" else 1):
            raise ValueError(f"{name} must be a "
                             f"{'non-negative' if name == 'lost_buffer' else 'positive'}"
                             f" integer, got {v!r}")
    check_finite_param("vb_rho", p.vb_rho, positive=True)
    check_finite_param("vb_alpha0", p.vb_alpha0, positive=True)


def build_graph(params: Params | None = None, name: str = "sort") -> FactorGraph:
    """The plate graph of ``params``: one target's Kalman box state, replicated."""
    p = params or Params()
    _check(p)
    p = at_frame_rate(p)
    if p.score_threshold is not None:
        p = replace(p, rounds=with_score_threshold(p.rounds, p.score_threshold),
                    activation=float(p.score_threshold), score_threshold=None)
    if p.motion != "kalman":
        return _particle_graph(p, name)
    q, r, p0 = _noise(p)
    labels, F, H = constant_velocity(p.box_state)
    variables = [Variable("box", len(labels), role="state", labels=tuple(labels))]
    mean = np.zeros(len(labels))
    mean[:4] = encode_boxes(REFERENCE_BOX, p.box_state)  # births re-centre it
    scaled = p.noise == "scale"
    rel_q = [p.pos_std] * 4 + [p.vel_std] * 4 if scaled else None
    rate0 = p.initial_rate_std or 10.0 * p.vel_std
    rel_p0 = [p.initial_pos_std or 2.0 * p.pos_std] * 4 + [rate0] * 4 if scaled else None
    rel_r = [p.meas_std] * 4 if scaled else None
    factors: list[Any] = [
        BoxPrior("box", mean=mean, cov=np.diag(p0), relative_std=rel_p0),
        BoxTransition("box", F=F, Q=np.diag(q), relative_std=rel_q, camera=p.camera_warp,
                      camera_order=p.camera_order),
        _association(p),
        AssignedDetectionLikelihood("box", H=H, R=np.diag(r), relative_std=rel_r,
                                    reupdate=p.reupdate, occlusion_gate=p.occlusion_gate,
                                    name="detection"),
    ]
    beliefs = {"box": "gaussian"}
    plate_vars = ["box"]
    if p.vb_noise:  # the variance of each measured component (relative with scale noise)
        variables.append(Variable("noise", 4, role="noise",
                                  labels=tuple(f"var_{c}" for c in labels[:4])))
        sigma = np.array(rel_r) if scaled else np.sqrt(r)
        factors += [InverseGammaPrior("noise", sigma=sigma, alpha=p.vb_alpha0),
                    NoiseForgetting("noise", rho=p.vb_rho, alpha_min=2.0),
                    VBNoise("noise", "box", likelihood="detection", name="vb")]
        plate_vars.append("noise")
    lc = _lifecycle(p)
    engine = EngineSettings(num_particles=1, beliefs=beliefs)
    meta = {"output": "box", "engine": engine.to_dict(), "readout": "plate",
            "reference_box": list(REFERENCE_BOX)}
    return FactorGraph(variables, factors, name=name, meta=meta,
                       plates=[Plate("target", tuple(plate_vars), lifecycle=lc)])


def _lifecycle(p: Params) -> Lifecycle:
    """The plate's life cycle of ``p`` (SORT's, ByteTrack's or OC-SORT's)."""
    max_lost = lost_frames(int(p.lost_buffer), p.fps)
    return Lifecycle(confirm_hits=int(p.min_hits), max_coast=0, max_lost=max_lost,
                     birth_counts=bool(p.birth_counts), match_iou=0.0,
                     birth_iou=float(p.birth_iou),
                     birth_min_score=float(p.activation), hit_log_odds=1.0, miss_log_odds=1.0,
                     confirm_on="streak" if p.consecutive else "hits",
                     recover_hits=int(p.recover_hits),
                     report="matched" if p.report == "estimate" else "detection",
                     tentative_lost=max_lost if p.keep_tentative else 0,
                     warmup_frames=int(p.min_hits) if p.warmup else 0,
                     activate_first=bool(p.activate_first),
                     explain_tentative=str(p.explain_tentative),
                     fill_gaps=int(math.floor(float(p.fill_gaps) * float(p.fps) + 1e-9)),
                     fill_after=None if p.fill_after is None else int(p.fill_after),
                     fill_births=bool(p.fill_births))


def _association(p: Params) -> DetectionAssociation:
    return DetectionAssociation(
        "box", rounds=[dict(r, appearance=True) if p.appearance and r.get(
            "against", "prediction") == "prediction" else r for r in p.rounds],
        score_map=p.score_map, placed_level=p.placed_level, gate_confidence=p.gate_confidence,
        direction_weight=p.direction_weight, delta_t=int(p.delta_t),
        appearance=appearance_factors(p.appearance), appearance_weight=p.appearance_weight,
        name="association")


def _particle_graph(p: Params, name: str) -> FactorGraph:
    """The cores with a particle box state (centre, size; and the GPDM's latent) moved by
    ``p.motion``: the association and the life cycle as the Kalman cores', the assigned
    detection's likelihood scale-aware (``meas_std`` of the box's size)."""
    from pgm.factors import AveragedVelocityTransition, GaussianPrior

    box = np.array(REFERENCE_BOX)
    if p.motion == "gpdm":
        from pathlib import Path

        from pgm.dynamics.factors import GPDMPrior, GPDMTransition
        from pgm.dynamics.gpdm import load_gpdm

        path = str(Path(p.gpdm).resolve())
        q = load_gpdm(path).latent_dim
        labels = ("cx", "cy", "w", "h") + tuple(f"z{k}" for k in range(q))
        motion = [GPDMPrior("box", model=path, mean=box),
                  GPDMTransition("box", model=path, fps=p.fps)]
    else:
        labels = ("cx", "cy", "w", "h")
        per_frame = 1.0 / np.sqrt(p.fps)
        pos = p.pos_noise * per_frame
        motion = [GaussianPrior("box", mean=box, cov=0.0),
                  AveragedVelocityTransition("box", noise_std=[pos, pos, 0.0, 0.0],
                                             window=1 if p.motion == "cv" else 3,
                                             scale_noise=p.scale_noise * per_frame,
                                             relative=True)]
    H = np.eye(4, len(labels))
    factors = motion + [
        _association(p),
        AssignedDetectionLikelihood("box", H=H, R=np.eye(4), relative_std=[p.meas_std] * 4,
                                    name="detection")]
    engine = EngineSettings(num_particles=int(p.num_particles))
    meta = {"output": "box", "engine": engine.to_dict(), "readout": "plate",
            "reference_box": box.tolist(), "motion": p.motion}
    return FactorGraph([Variable("box", len(labels), role="state", labels=labels)], factors,
                       name=name, meta=meta,
                       plates=[Plate("target", ("box",), lifecycle=_lifecycle(p))])


#: the options of SORT and ByteTrack on the command line
OPTIONS = (
    _config.Option("--box-state", "box_state", choices=BOX_STATES,
                   help="the state's box code: xyxy (corners, as the trackers package; "
                        "default) or xysr (centre, area, aspect: the SORT paper)"),
    _config.Option("--noise", "noise", choices=NOISES,
                   help="fixed (pixels, as the trackers package; default) or scale (each std a "
                        "fraction of the box's size: BoT-SORT's scale-aware Kalman noise)"),
    _config.Option("--report", "report", choices=REPORTS,
                   help="the box a matched track reports: detection (as the trackers package; "
                        "default) or estimate (the Kalman posterior mean)"),
    _config.Option("--appearance", "appearance", metavar="CUE[+CUE...]",
                   help="appearance cues for association and re-identification, e.g. colour "
                        "or fragments (one model per track; default: none, IoU only)"),
    _config.Option("--appearance-weight", "appearance_weight",
                   type=_config.finite_float("--appearance-weight"),
                   help="weight of the appearance similarity against the IoU (default 0.5)"),
    _config.Option("--motion", "motion", choices=MOTIONS,
                   help="kalman (the exact Kalman box state; default) or particles moved by cv, "
                        "cv3 (velocity averaged over three frames) or gpdm (--gpdm FILE)"),
    _config.Option("--gpdm", "gpdm", metavar="FILE.npz",
                   help="the learned GPDM of --motion gpdm (pgm learn gpdm)"),
    _config.Option("--occlusion-gate", "occlusion_gate",
                   type=_config.finite_float("--occlusion-gate"), metavar="SIGMA",
                   help="edges of a detection inside the predicted box by more than SIGMA "
                        "innovation stds are taken as hidden (corner states; default: off)"),
    _config.Option("--vb-noise", "vb_noise", flag_only=True,
                   help="Feng et al.'s (2015) variational-Bayes measurement noise per target"),
    _config.Option("--scores", "score_map", choices=("detector",) + LEARNED_SCORE_MAPS,
                   help="what the score thresholds read: detector (the detector's own numbers, "
                        "mapped through the logistic when outside [0, 1]: the trackers "
                        "package), learned (the probability that a detection is of a target, "
                        "learned on the video from which detections are found again), "
                        "quantile (the score's quantile among the video's scores), "
                        "quantile-gated (that quantile, 0 where the video shows detections "
                        "more likely clutter than not: a detector run at a lower threshold) "
                        "quantile-rebased (the quantile among the detections above that "
                        "clutter), placed (the gated quantile, the detections below the "
                        "threshold kept where the tracks show them on their people as "
                        "often as the best-scored ones: a detector run at a higher "
                        "threshold), placed-rebased (the same over the rebased quantile: "
                        "either threshold) or placed-over (that, and the boxes on a tracked "
                        "person kept where the video reads their score as clutter: a "
                        "crowd); all but detector give the same tracks for any "
                        "increasing map of the scores. Default: the model's"),
    _config.Option("--reference-fps", "reference_fps",
                   type=_config.finite_float("--reference-fps"), metavar="FPS",
                   help="read the per-frame constants (confirmation, OC-SORT's momentum "
                        "window, the Kalman noise) as at FPS frames/s and convert them to the "
                        "video's rate, so that behaviour per second does not depend on the "
                        "frame rate (default: the model's; the classic cores: per frame)"),
    _config.Option("--score-threshold", "score_threshold",
                   type=_config.finite_float("--score-threshold"), metavar="P",
                   help="every score threshold (the confident detections' and a new track's) "
                        "at P (with --scores learned a probability; default: the model's)"),
    _config.Option("--lost-track-buffer", "lost_buffer",
                   type=_config.int_in("--lost-track-buffer", 0, 100000), metavar="FRAMES",
                   help="frames (at 30 frames/s: scaled to the video's rate, as the trackers "
                        "package and ByteTrack do) a confirmed track is kept without a match, "
                        "to be found again (default: the model's, 30)"),
    _config.Option("--min-hits", "min_hits", type=_config.int_in("--min-hits", 1, 100000),
                   metavar="N",
                   help="matches before a new track is reported (ByteTrack and BoT-SORT: in a "
                        "row, the trackers package's minimum consecutive frames; default: the "
                        "model's)"),
    _config.Option("--recover-hits", "recover_hits",
                   type=_config.int_in("--recover-hits", 1, 100000), metavar="N",
                   help="matches in a row before a lost track found again is reported (1: at "
                        "once, SORT and ByteTrack; default: the model's, ocsort-colour 3)"),
    _config.Option("--birth-iou", "birth_iou", type=_config.finite_float("--birth-iou"),
                   metavar="T",
                   help="no track is born on a detection overlapping a track's predicted box "
                        "(or another birth) by IoU above T: a second box on a person starts no "
                        "second identity (1: off, the trackers package's cores; default: the "
                        "model's, ocsort-colour 0.3)"),
    _config.Option("--explain-tentative", "explain_tentative",
                   choices=EXPLAIN_TENTATIVE,
                   help="remove a track not yet confirmed when its detection is one a confirmed "
                        "track explains: overlapping its predicted box, or a higher-scored "
                        "detection it was given, by more than --birth-iou (default: the "
                        "model's)"),
    _config.Option("--fill-gaps", "fill_gaps", type=_config.finite_float("--fill-gaps"),
                   metavar="SECONDS",
                   help="a track found again after at most SECONDS without a match also "
                        "reports the frames between (boxes interpolated), written to the track "
                        "file when it is found (0: never; default: the model's)"),
    _config.Option("--fill-after", "fill_after",
                   type=_config.int_in("--fill-after", 1, 100000), metavar="N",
                   help="matches in a row a track found again needs before its gap is filled "
                        "(1: at once; default: the matches a new track needs)"),
    _config.Option("--fill-births", "fill_births", type=_config.on_off("--fill-births"),
                   metavar="{on,off}",
                   help="a track confirmed also reports the frames it was tentative in, written "
                        "when it is confirmed (default: the model's, ocsort-colour on)"),
    _config.Option("--count-hits", "count_hits", choices=HIT_COUNTS,
                   help="what --min-hits and --recover-hits count with --reference-fps: frames "
                        "at that rate, converted to the video's (seconds), or detections at any "
                        "rate (default: seconds)"),
    _config.Option("--noise-per", "noise_per", choices=NOISE_PERS,
                   help="how the Kalman process noise converts with --reference-fps: a random "
                        "walk in time (second) or the same step each detection, its rates in "
                        "the video's units (detection; default: the model's, ocsort-colour "
                        "detection)"),
    _config.Option("--iou-threshold", None, type=_config.finite_float("--iou-threshold"),
                   metavar="T",
                   help="the IoU a detection needs with a track to be matched to it, in every "
                        "association round (default: the model's, e.g. SORT 0.3, ByteTrack "
                        "0.1)"),
)


def video_build(config: _config.ModelConfig, values: dict[str, Any],
                video: _config.VideoInfo) -> FactorGraph:
    """The model for ``video``: its frame rate and, from its detections' scores, the score
    map (:func:`score_map_for`)."""
    params = config.module.Params()
    kw: dict[str, Any] = {o.field: values[o.dest] for o in config.options
                          if o.field is not None and _config.given(values.get(o.dest))}
    kw["fps"] = float(video.fps)
    if video.particles is not None:
        kw["num_particles"] = int(video.particles)
    # detections from a file have scores whose scale the file tells (score_map_for); a
    # detector without one (background subtraction: fill fractions) says nothing of
    # confidence, so its detections are all taken as confident
    iou = values.get("iou_threshold")
    if iou is not None:
        if not 0.0 <= iou <= 1.0:
            raise ValueError(f"--iou-threshold must be in [0, 1], got {iou}")
        kw["rounds"] = tuple(dict(r, iou=float(iou)) for r in params.rounds)
    choice = kw.pop("score_map", None)  # --scores: detector or a learned map
    if choice == "detector" and "score_threshold" not in kw:
        kw["score_threshold"] = None  # the core's own thresholds, on the detector's numbers
    reading = choice or params.score_map
    if video.score_range is None:
        kw["score_map"] = "constant"
    elif reading in LEARNED_SCORE_MAPS:
        kw["score_map"] = reading
    else:
        kw["score_map"] = score_map_for(np.asarray(video.score_range))
    return config.module.build_graph(replace(params, **kw), name=config.name)


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "sort", "multi-target", sys.modules[__name__],
    "SORT: a Kalman box state per target, Hungarian association on IoU (Bewley et al. 2016)",
    options=OPTIONS, build=video_build)
