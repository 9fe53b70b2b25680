"""The particle PHD filter [#vo2005] as a model config: one ``set`` variable.

``targets`` holds every target's state ``[px, vx, py, vy]`` (state order of the bench
scenario and Stone Soup; matrices are built from named components). For video the
measurements are detection *foot points* (bottom-centre of a box) in pixels and the
velocities are in pixels per frame; each reported box takes its size from the
detections associated with the track (an exponential average), not from the state.

Factors: an empty :class:`~pgm.factors.multitarget.IntensityPrior` (targets are born from
measurements), a nearly-constant-velocity :class:`~pgm.LinearGaussianTransition` with
survival ``p_S``, and a :class:`~pgm.factors.multitarget.PHDLikelihood` with detection
probability, Poisson clutter and measurement-driven births [#ristic2012].

>>> from pgm.models import phd
>>> g = phd.build_graph(phd.Params(area=768 * 576))
>>> [f.kind for f in g.factors.values()]
['prior', 'transition', 'likelihood']

References
----------
.. [#vo2005] B.-N. Vo, S. Singh and A. Doucet, "Sequential Monte Carlo methods for multitarget
   filtering with random finite sets", IEEE Trans. Aerospace and Electronic Systems 41(4),
   1224–1245, 2005. doi:10.1109/TAES.2005.1561884
.. [#ristic2012] B. Ristic, D. Clark, B.-N. Vo and B.-T. Vo, "Adaptive target birth intensity
   for PHD and CPHD filters", IEEE Trans. Aerospace and Electronic Systems 48(2),
   1656–1668, 2012. doi:10.1109/TAES.2012.6178085
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.core.numerics import check_finite_param
from pgm.core.readout import Targets, register_readout
from pgm.core.variable import Variable
from pgm.factors import LinearGaussianTransition
from pgm.factors.multitarget import (
    IntensityPrior,
    PHDLikelihood,
    ScoreSettings,
    TrackSettings,
    constant_velocity,
)
from pgm.inference.settings import EngineSettings

from . import config as _config

__all__ = ["CONFIG", "Params", "build_graph", "video_params", "foot_point_boxes", "STATE_LABELS",
           "H_POSITION", "SCALE_STATE_LABELS", "H_SCALE", "REFERENCE_HEIGHT"]

STATE_LABELS = ("px", "vx", "py", "vy")
H_POSITION = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
#: the scale-aware state: the foot point, the log-height and their rates
SCALE_STATE_LABELS = ("px", "vx", "py", "vy", "log_h", "v_log_h")
H_SCALE = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 1.0, 0, 0, 0], [0, 0, 0, 0, 1.0, 0]])


@dataclass(frozen=True)
class Params:
    """Settings of the (VB-)PHD filter; defaults are for pedestrians' foot points in pixels.

    Attributes
    ----------
    area : float
        Measurement-space area (image width × height, px²).
    sigma : float
        Measurement noise std (px) — fixed for the PHD, the initial value for VB-PHD.
    q : float
        Process-noise spectral density of the constant-velocity model (px²/frame³).
    dt : float
        Time step (1 frame).
    p_detect, p_survive : float
    clutter_rate : float
        Expected clutter measurements per frame.
    birth_rate : float
        Expected births per frame (λ_b; 0.1–0.2 works).
    n_birth : int
        Newborn particles per measurement.
    birth_velocity_std : float
        σ of newborn velocities (px/frame): about a typical speed.
    particles_per_target, min_particles : int
        Resampling budget ``max(min_particles, round(particles_per_target · mass))``.
    regularise : bool
        Regularised resampling: each target's resampled particles spread again by a kernel
        of its own posterior (:mod:`pgm.inference.phd_regularise`).
    confirm_hits, max_coast : int
        Track layer: hits to confirm, frames to coast.
    max_lost : int, optional
        Track layer: frames a confirmed track is kept (unreported) for re-identification
        after coasting (default: no lost stage).
    merge_gate : float
        Extraction: estimates closer than this many σ are one target (default 2).
    scale_aware : bool
        Track the box's scale: state ``[px, vx, py, vy, log_h, v_log_h]``, measurements
        ``(foot x, foot y, log h)``, and every length — ``sigma``, ``q``,
        ``birth_velocity_std`` — in units of the target's *own* height (``sigma = 0.08``
        is 8 % of it), so that one setting serves near and far targets; a VB noise
        belief then learns the relative variance.
    sigma_log_h : float
        Scale-aware: noise std of a detection's log-height.
    q_log_h : float
        Scale-aware: process-noise density of the log-height (per frame³).
    log_h_range : float
        Scale-aware: the extent of log-heights where clutter and births appear.
    score_model : str
        How detection scores enter the measurement model (:mod:`pgm.factors.scores`):
        ``"off"`` (score-blind, the filter before scores were used), ``"mixture"``
        (a per-detection clutter intensity from a two-class mixture fitted online to the
        video's own scores; low-score detections only update existing targets) or
        ``"learned"`` (the same terms from the probability that a detection is of a
        target, learned on the video from which detections are found again: the same
        for any strictly increasing map of the scores).
    score_temper : float
        Exponent ``γ`` of the score likelihood ratio.
    score_max_ratio : float
        The score likelihood ratio is clipped to ``[1/r, r]``.
    score_birth_min_prob : float
        No births from detections whose posterior probability of being a target is below
        this (0: every detection may start a target).
    score_min_samples : int
        Detection scores collected before the first mixture fit (score-blind until then).
    clutter_from_scores : bool
        Calibrate the clutter rate from the score mixture (``(1 − π) ×`` detections per
        frame) instead of ``clutter_rate``.
    score_persisting : str
        The score density of a persisting target's detection, ``"target"`` (literal) or
        ``"all"`` (the marginal of every detection): see
        :class:`~pgm.factors.scores.ScoreSettings`.
    score_shadow_iou : float
        Detections overlapping a higher-scored one by at least this IoU start no births
        (0: off); see :func:`~pgm.factors.scores.shadowed`.
    """

    area: float = 640.0 * 480.0
    sigma: float = 6.0
    q: float = 1.0
    dt: float = 1.0
    p_detect: float = 0.9
    p_survive: float = 0.99
    clutter_rate: float = 2.0
    birth_rate: float = 0.1
    n_birth: int = 100
    birth_velocity_std: float = 4.0
    particles_per_target: int = 300
    min_particles: int = 200
    regularise: bool = False
    confirm_hits: int = 3
    max_coast: int = 2
    max_lost: int | None = None
    merge_gate: float = 2.0
    scale_aware: bool = False
    sigma_log_h: float = 0.1
    q_log_h: float = 1e-5
    log_h_range: float = 3.0
    score_model: str = "off"
    score_temper: float = 1.0
    score_max_ratio: float = 100.0
    score_birth_min_prob: float = 0.5
    score_min_samples: int = 50
    clutter_from_scores: bool = False
    score_persisting: str = "target"
    score_shadow_iou: float = 0.0


#: score settings of :func:`video_params`, chosen leave-one-sequence-out
#: (docs/phd_video_defaults.md)
VIDEO_SCORE_SETTINGS = {"score_model": "learned", "score_temper": 0.5,
                        "score_birth_min_prob": 0.0, "score_persisting": "all",
                        "score_shadow_iou": 0.4}
#: VB noise settings of :func:`video_params` (applied when ``cls`` has the fields, i.e.
#: :class:`pgm.models.vb_phd.Params`), chosen leave-one-sequence-out (docs/phd_video_defaults.md)
VIDEO_VB_SETTINGS = {"rho": 0.9, "isotropic_noise": True}
REFERENCE_HEIGHT = 75.0  # px: a pedestrian's box height in PETS09-S2L1 (median detection)


def video_params(cls, width: int, height: int, fps: float,
                 typical_height: float | None = None, lost_seconds: float = 1.0,
                 scale_aware: bool = False, **overrides):
    """``Params`` for pedestrians' foot points in a ``width × height`` video at ``fps``.

    Lengths are in units of a typical person's box height ``h`` (``typical_height``,
    e.g. the median height of the sequence's detections; 75 px when unknown) and
    speeds per *second*, converted to pixels per frame: measurement σ = 0.08 h,
    newborn velocity σ = 0.4 h/s, process noise q = 0.053 h²/s³ (``q_frame = q/fps³``)
    — 6 px, 30 px/s and 300 px²/s³ at h = 75 px. Confirmed tracks are kept for
    re-identification for ``lost_seconds`` (``max_lost`` frames; 0: off); estimates
    closer than ``merge_gate = 3`` σ are merged. With ``scale_aware=True`` the same
    lengths are in units of *each target's own* height (``typical_height`` unused), and a
    detection's log-height has σ 0.1 with a rate process noise of 0.04 /s³. Detection
    scores (``score_model``, :mod:`pgm.factors.scores`) are on by default with the
    settings of ``VIDEO_SCORE_SETTINGS`` (the shadow rule at IoU 0.4); for VB-PHD (``cls``
    with the noise fields) the noise belief is isotropic with forgetting ρ = 0.9
    (``VIDEO_VB_SETTINGS``). How each of these defaults was chosen, with the measured
    figures and the commands that measure them: ``docs/phd_video_defaults.md``.
    Everything else keeps the class defaults unless overridden.
    """
    fps = float(fps) if fps and fps > 0 else 25.0
    lost = int(round(lost_seconds * fps)) if lost_seconds > 0 else None
    names = {f.name for f in dataclasses.fields(cls)}
    vb = {k: v for k, v in VIDEO_VB_SETTINGS.items() if k in names}
    if overrides.get("score_model") == "off":  # score-blind: no shadow rule either
        overrides = {"score_shadow_iou": 0.0, **overrides}
    overrides = {**VIDEO_SCORE_SETTINGS, **vb, **overrides}
    if scale_aware:
        kw = dict(area=float(width) * float(height), sigma=6.0 / REFERENCE_HEIGHT,
                  birth_velocity_std=30.0 / REFERENCE_HEIGHT / fps,
                  q=300.0 / REFERENCE_HEIGHT**2 / fps**3, scale_aware=True,
                  sigma_log_h=0.1, q_log_h=0.04 / fps**3,
                  log_h_range=float(np.log(max(float(height), 40.0) / 20.0)),
                  max_lost=lost, merge_gate=3.0)
        kw.update(overrides)
        return cls(**kw)
    k = 1.0
    if typical_height is not None and np.isfinite(typical_height) and typical_height > 0:
        k = float(typical_height) / REFERENCE_HEIGHT
    kw = dict(area=float(width) * float(height), sigma=6.0 * k,
              birth_velocity_std=30.0 * k / fps, q=300.0 * k * k / fps**3,
              max_lost=lost, merge_gate=3.0)
    kw.update(overrides)
    return cls(**kw)


def build_graph(params: Params, name: str = "phd") -> FactorGraph:
    """The one-variable PHD graph ``prior → targets ← CV``, ``targets — PHD — Z``."""
    for field in ("area", "sigma", "dt"):
        check_finite_param(field, getattr(params, field), positive=True)
    if params.scale_aware:
        for field in ("sigma_log_h", "q_log_h", "log_h_range"):
            check_finite_param(field, getattr(params, field), positive=True)
        F, Q = constant_velocity(params.dt, params.q, "pv", q_log_h=params.q_log_h)
        labels, H, d = SCALE_STATE_LABELS, H_SCALE, 6
        R = [params.sigma**2] * 2 + [params.sigma_log_h**2]
        scale = {"scale_index": 4}
        trans = LinearGaussianTransition("targets", F=F, Q=Q, p_survive=params.p_survive,
                                         scaled=[True] * 4 + [False] * 2, **scale)
        scale["log_h_range"] = params.log_h_range
    else:
        F, Q = constant_velocity(params.dt, params.q, "pv")
        labels, H, d, R, scale = STATE_LABELS, H_POSITION, 4, [params.sigma**2] * 2, {}
        trans = LinearGaussianTransition("targets", F=F, Q=Q, p_survive=params.p_survive)
    targets = Variable("targets", d, role="set", labels=labels)
    factors = [
        IntensityPrior("targets", mean=np.zeros(d), mass=0.0),
        trans,
        PHDLikelihood("targets", H=H, R=R,
                      p_detect=params.p_detect, clutter_rate=params.clutter_rate,
                      area=params.area, birth_rate=params.birth_rate, n_birth=params.n_birth,
                      birth_velocity_std=params.birth_velocity_std, velocity_indices=(1, 3),
                      min_particles=int(params.min_particles),
                      regularise=params.regularise,
                      merge_gate=float(check_finite_param("merge_gate", params.merge_gate,
                                                          positive=True)),
                      tracks=TrackSettings(
                          confirm_hits=int(params.confirm_hits), max_coast=int(params.max_coast),
                          max_lost=None if params.max_lost is None else int(params.max_lost)),
                      scores=ScoreSettings(
                          model=params.score_model, temper=float(params.score_temper),
                          max_ratio=float(params.score_max_ratio),
                          birth_min_prob=float(params.score_birth_min_prob),
                          min_samples=int(params.score_min_samples),
                          clutter_from_scores=bool(params.clutter_from_scores),
                          persisting=params.score_persisting,
                          shadow_iou=float(params.score_shadow_iou)),
                      **scale),
    ]
    engine = EngineSettings(num_particles=int(params.particles_per_target))
    return FactorGraph([targets], factors, name=name,
                       meta={"output": "targets", "engine": engine.to_dict(),
                             "readout": "phd-foot-points"})


@register_readout("phd-foot-points")
def foot_point_boxes(graph: FactorGraph, record) -> Targets:
    """Reported tracks as boxes: the state ``[px, vx, py, vy]`` is a foot point
    (bottom-centre) and the size comes from the track's associated detections; tracks
    with no size yet are not reported."""
    est = record.estimates[graph.output[0]]
    ok = np.all(np.isfinite(est["sizes"]), axis=1)
    ids, states, sizes = est["ids"][ok], est["states"][ok], est["sizes"][ok]
    labels = graph.variables[graph.output[0]].labels or ()
    if "log_h" in labels and len(ids):  # scale-aware state: its height, the detections' aspect
        h = np.exp(states[:, labels.index("log_h")])
        sizes = np.column_stack([sizes[:, 0] / sizes[:, 1] * h, h])
    boxes = (np.column_stack([states[:, 0] - sizes[:, 0] / 2, states[:, 2] - sizes[:, 1], sizes])
             if len(ids) else np.zeros((0, 4)))
    return Targets(ids, boxes, est["existence"][ok], text=f"E[N]={est['expected_count']:.1f}")


def video_build(config, values, video):
    """The graph of a (VB-)PHD config for ``video`` (:func:`video_params`), with the
    options ``--scale-aware``, ``--scores``, ``--per-track-noise`` and ``--dbn``."""
    kwargs: dict = {}
    if video.particles is not None:
        kwargs["particles_per_target"] = int(video.particles)
    if values.get("per_track_noise"):
        kwargs["per_track_noise"] = True
    if video.typical_height is not None:
        kwargs["typical_height"] = float(video.typical_height)
    if values.get("scale_aware"):
        kwargs["scale_aware"] = True
    if values.get("scores") is not None:
        kwargs["score_model"] = values["scores"]
    graph = config.module.build_graph(video_params(config.module.Params, video.width,
                                                   video.height, video.fps, **kwargs))
    if values.get("dbn") is not None:
        from pgm.observation.appearance.dbn import DBNLikelihood

        graph = graph.with_factors(DBNLikelihood(graph.output[0], model=values["dbn"],
                                                 name="appearance:dbn"),
                                   name=graph.name + "+dbn")
    return graph


#: the (VB-)PHD options (:mod:`pgm.models.config`)
PHD_OPTIONS = (
    _config.Option("--dbn", None, metavar="FILE.npz",
                   help="a DBN person likelihood trained by 'pgm learn dbn' (multiplies the "
                        "detection terms; default: none)"),
    _config.Option("--scale-aware", "scale_aware", flag_only=True,
                   help="track each box's scale; noise in units of each target's own height "
                        "(experimental: see docs/results.md)"),
    _config.Option("--scores", "score_model", choices=("off", "mixture", "learned"),
                   help="detection scores in the measurement model: 'learned' (default: "
                        "the probability that a detection is of a target, learned on the "
                        "video from which detections are found again, read from the score's "
                        "rank: the same for any increasing map of the scores), 'mixture' (a "
                        "two-class score mixture fitted on the video's own scores: the same "
                        "for any affine map) or 'off' (score-blind)"))

#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "phd", "multi-target", sys.modules[__name__],
    "the particle PHD filter (Vo, Singh & Doucet 2005) on detections' foot points",
    options=PHD_OPTIONS, build=video_build)
