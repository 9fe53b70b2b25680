"""Wang, Yin & Man's tracker (2008): a particle filter per person whose proposals come from a GPDM.

A plate (one sub-graph per person, :class:`pgm.inference.Engine`) over one
``part`` variable ``person = (cx, cy, w, h, z_0 … z_{q−1})``: the box and the person's
``q``-dimensional latent coordinate of a Gaussian-process dynamical model learned from
trajectories (``pgm learn gpdm``, :mod:`pgm.dynamics.gpdm`). The factors:

* :class:`~pgm.dynamics.factors.GPDMPrior` — at a person's birth the box is the
  detection and the latent particles are drawn from the training latents, so the
  weights select the latents whose predicted motion the frames confirm (the Bayesian
  reading of "the test-time latent from the last few differences");
* :class:`~pgm.dynamics.factors.GPDMTransition` — ``z' ~ N(μ_X(z), σ²_X(z))`` mapped
  through ``μ_Y`` to the box change in box heights per second (the fixes of
  :mod:`pgm.dynamics.gpdm`); the learned dynamics live once, in the model file, shared by every person;
* the paper's appearance models as likelihood factors: the RGB histogram (default), and
  by ``appearance`` the GMM-KL (``gmm``) and rotation-invariant (``rings``) models;
* the frame's detections (:class:`~pgm.factors.plates.DetectionLikelihood`) and mutual
  exclusion between persons, births and deaths from detections (as :mod:`.multi_pf`).

``motion="cv"`` and ``motion="cv3"`` swap the GPDM for constant velocity and constant
velocity averaged over three frames (the paper's baselines), everything else equal.
Missing frames are predicted through (``pgm track --drop-frames``).

Departure from the paper: it stacks all ``n`` targets into one ``6n``-dimensional
vector; here each person has its own chain with the dynamics shared.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.core.numerics import check_finite_param
from pgm.core.plate import Lifecycle, Plate
from pgm.core.variable import Variable
from pgm.factors import AveragedVelocityTransition, GaussianPrior
from pgm.inference.settings import EngineSettings
from pgm.observation.appearance.cues import appearance_cues

from . import config as _config
from .multi_pf import REFERENCE_BOX, evidence_factors
from .part_graph import BOX_LABELS

__all__ = ["CONFIG", "Params", "build_graph", "MOTIONS"]

MOTIONS = ("gpdm", "cv", "cv3")


@dataclass(frozen=True)
class Params:
    """Settings of the GPDM tracker.

    Attributes
    ----------
    model : str, optional
        Path of a GPDM ``.npz`` written by ``pgm learn gpdm`` (required for
        ``motion="gpdm"``).
    motion : {"gpdm", "cv", "cv3"}
        The motion model.
    fps : float
        The video's frame rate (the GPDM works in box heights per second; the baselines'
        noise is per √s as in :mod:`.multi_pf`).
    num_particles : int
        Particles per person (the paper uses about 20).
    appearance : str
        Appearance cues joined by ``+``: ``colour`` (an RGB histogram here), ``gmm``,
        ``rings`` or any other cue of :data:`pgm.observation.appearance.cues.CUES`.
    lam, layout, kernel :
        Colour-likelihood settings (``layout="rgb"``: the paper's RGB histogram).
    pos_noise, scale_noise : float
        Baselines' noise per √s (box heights; log-scale).
    latent_noise_scale : float
        Multiplies the GPDM's latent predictive std.
    detection_pos_std, detection_size_std, detection_strength, exclusion :
        As in :class:`pgm.models.multi_pf.Params`.
    lifecycle : Lifecycle
    """

    model: str | None = None
    motion: str = "gpdm"
    fps: float = 25.0
    num_particles: int = 20
    appearance: str = "colour"
    lam: float = 20.0
    layout: str = "rgb"
    kernel: str = "uniform"
    pos_noise: float = 0.185
    scale_noise: float = 0.05
    latent_noise_scale: float = 1.0
    detection_pos_std: float = 0.05
    detection_size_std: float = 0.1
    detection_strength: float = 2000.0
    exclusion: float = 10.0
    lifecycle: Lifecycle = field(default_factory=Lifecycle)


def build_graph(params: Params | None = None, name: str = "gpdm") -> FactorGraph:
    """The plate graph of ``params``."""
    p = params or Params()
    if p.motion not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {p.motion!r}")
    check_finite_param("fps", p.fps, positive=True)
    if isinstance(p.num_particles, bool) or int(p.num_particles) != p.num_particles or \
            p.num_particles < 1:
        raise ValueError(f"num_particles must be a positive integer, got {p.num_particles!r}")
    appearance_cues(p.appearance)
    box = np.asarray(REFERENCE_BOX)
    nm = "person"
    if p.motion == "gpdm":
        from pgm.dynamics.factors import GPDMPrior, GPDMTransition
        from pgm.dynamics.gpdm import load_gpdm

        if p.model is None:
            raise ValueError("the gpdm motion model needs a learned GPDM file (pgm learn gpdm; "
                             "pgm track --gpdm FILE)")
        path = str(Path(p.model).resolve())  # a saved graph reloads from any folder
        q = load_gpdm(path).latent_dim
        labels = BOX_LABELS + tuple(f"z{k}" for k in range(q))
        variable = Variable(nm, 4 + q, role="part", labels=labels)
        factors = [GPDMPrior(nm, model=path, mean=box),
                   GPDMTransition(nm, model=path, fps=p.fps,
                                  latent_noise_scale=p.latent_noise_scale)]
    else:
        per_frame = 1.0 / np.sqrt(p.fps)
        pos = p.pos_noise * per_frame
        variable = Variable(nm, 4, role="part", labels=BOX_LABELS)
        factors = [GaussianPrior(nm, mean=box, cov=0.0),
                   AveragedVelocityTransition(nm, noise_std=[pos, pos, 0.0, 0.0],
                                              window=1 if p.motion == "cv" else 3,
                                              scale_noise=p.scale_noise * per_frame,
                                              relative=True)]
    factors += evidence_factors(nm, p)
    engine = EngineSettings(num_particles=int(p.num_particles))
    meta = {"output": nm, "engine": engine.to_dict(), "readout": "plate",
            "reference_box": list(REFERENCE_BOX), "motion": p.motion}
    return FactorGraph([variable], factors, name=name if p.motion == "gpdm" else
                       f"{name}-{p.motion}", meta=meta,
                       plates=[Plate(nm, (nm,), lifecycle=p.lifecycle)])


def _build(config, values, video):
    motion = values.get("motion") or "gpdm"
    path = values.get("gpdm")
    if motion == "gpdm":
        if path is None:
            raise ValueError("--model gpdm needs --gpdm FILE.npz (learn one with 'pgm learn "
                             "gpdm'), or --motion cv|cv3 for the baselines")
        if not Path(path).is_file():
            raise ValueError(f"--gpdm: no such file: {path}")
    elif path is not None:
        raise ValueError(f"--gpdm applies to --motion gpdm, not {motion}")
    values = {**values, "motion": motion}
    return _config.default_build(config, values, video)


def _example(config, values):
    if values.get("gpdm") is None and values.get("motion") in (None, "gpdm"):
        values = {**values, "motion": "cv3"}
        note = ("drawn with --motion cv3 (the learned dynamics need --gpdm FILE.npz: "
                "'pgm learn gpdm')")
    else:
        note = ""
    return _build(config, values, _config.VideoInfo()), note


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "gpdm", "multi-target", sys.modules[__name__],
    "a particle filter per person with proposals from a learned GPDM (Wang, Yin & Man "
    "2008), as a plate",
    options=(_config.APPEARANCE, _config.SCALE_NOISE,
             _config.Option("--gpdm", "model", metavar="FILE.npz",
                            help="the learned dynamics ('pgm learn gpdm'); needed by --motion "
                                 "gpdm (default: none)"),
             _config.Option("--motion", "motion", choices=MOTIONS,
                            help="the motion model: the learned GPDM (default), constant "
                                 "velocity, or constant velocity averaged over three frames")),
    build=_build, example=_example)
