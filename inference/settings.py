"""Typed engine settings: what a model config asks of the engine, saved with the graph.

A model config builds an :class:`EngineSettings` and stores ``settings.to_dict()`` as
``graph.meta["engine"]``; :class:`~pgm.inference.Engine` reads it back with
:meth:`from_dict` (an unknown key is a ``ValueError`` naming it, not a silently ignored
string), lets its keyword arguments override single fields, and writes the full
effective settings back into its own copy of the graph, so a run's saved
``model.json`` holds every engine setting that shaped it. Settings of one factor (a PHD
filter's merge gate, its track layer) live on that factor instead.

>>> s = EngineSettings(num_particles=50, fusion="product")
>>> EngineSettings.from_dict(s.to_dict()) == s
True
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["EngineSettings", "FUSIONS", "MESSAGE_WEIGHTS", "BELIEF_FORMS", "register_belief_form"]

FUSIONS = ("mixture", "product")
MESSAGE_WEIGHTS = ("source", "target")


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _builtin_forms() -> dict[str, type]:
    from pgm.core.beliefs import Intensity, Particles
    from pgm.core.expfam import Gaussian, InverseGamma

    return {"particles": Particles, "gaussian": Gaussian, "intensity": Intensity,
            "inverse-gamma": InverseGamma}


#: the belief forms a model may declare for a variable (``EngineSettings.beliefs``): name
#: -> belief class (:func:`register_belief_form` adds one)
BELIEF_FORMS: dict[str, type] = _builtin_forms()


def register_belief_form(name: str, belief_type: type) -> None:
    """Let models declare ``belief_type`` for a variable by ``name`` (saved in their
    ``model.json``), as ``"gaussian"`` names :class:`~pgm.core.expfam.Gaussian`."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"a belief form is named by a non-empty string, got {name!r}")
    if not isinstance(belief_type, type):
        raise ValueError(f"belief form {name!r}: expected a class, got {belief_type!r}")
    BELIEF_FORMS[name] = belief_type


@dataclass(frozen=True)
class EngineSettings:
    """Settings of the generic engine.

    Attributes
    ----------
    num_particles : int or dict
        Particles per variable (one int for all, or variable name → int; variables not
        named get 100). For a ``set`` variable: particles per expected target.
    resampling : str
        ``"systematic"``, ``"multinomial"``, ``"stratified"`` or ``"residual"``.
    ess_threshold : float
        Resample when ESS < ``ess_threshold`` × N (1: every frame).
    inframe_iterations : int
        Flooding rounds of the in-frame phase on loopy graphs and VB fixed-point sweeps
        per frame (trees need one sweep).
    fusion : {"mixture", "product"}
        Particle-BP fusion rule (:mod:`pgm.inference.pbp`).
    message_weight : {"source", "target"}
        Mixture messages carry the source's likelihood or the target's at the message
        particle.
    message_particles : int, optional
        Message particles per coupling message (default: one per source particle).
    beliefs : dict, optional
        Variable name → belief form, overriding the one of its role: ``"particles"``,
        ``"gaussian"`` (exact Kalman rules), ``"intensity"``, ``"inverse-gamma"`` (what a
        model declares; ``Engine(belief_types=...)`` overrides it with classes).
    """

    num_particles: int | dict[str, int] = 100
    resampling: str = "systematic"
    ess_threshold: float = 0.5
    inframe_iterations: int = 1
    fusion: str = "mixture"
    message_weight: str = "source"
    message_particles: int | None = None
    beliefs: dict[str, str] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.num_particles, dict):
            for k, v in self.num_particles.items():
                _positive_int(f"num_particles[{k!r}]", v)
        else:
            object.__setattr__(self, "num_particles",
                               _positive_int("num_particles", self.num_particles))
        if not isinstance(self.resampling, str) and not callable(self.resampling):
            raise ValueError(f"resampling must be a scheme name, got {self.resampling!r}")
        try:
            t = float(self.ess_threshold)
        except (TypeError, ValueError):
            t = float("nan")  # refused below, naming the setting
        if not np.isfinite(t) or not 0.0 <= t <= 1.0:
            raise ValueError(f"ess_threshold must be in [0, 1], got {self.ess_threshold!r}")
        object.__setattr__(self, "ess_threshold", t)
        if isinstance(self.inframe_iterations, bool) or not isinstance(
                self.inframe_iterations, (int, np.integer)) or self.inframe_iterations < 0:
            raise ValueError(f"inframe_iterations must be >= 0, got {self.inframe_iterations!r}")
        if self.fusion not in FUSIONS:
            raise ValueError(f"unknown fusion {self.fusion!r} (choose from {FUSIONS})")
        if self.message_weight not in MESSAGE_WEIGHTS:
            raise ValueError(f"message_weight must be 'source' or 'target', got "
                             f"{self.message_weight!r}")
        if self.message_particles is not None:
            object.__setattr__(self, "message_particles",
                               _positive_int("message_particles", self.message_particles))
        if self.beliefs is not None:
            if not isinstance(self.beliefs, dict) or any(
                    not isinstance(v, str) or v not in BELIEF_FORMS for v in self.beliefs.values()):
                raise ValueError(f"beliefs must map variable names to one of "
                                 f"{sorted(BELIEF_FORMS)}, got {self.beliefs!r}")
            object.__setattr__(self, "beliefs", dict(self.beliefs))

    def particle_counts(self, graph: Any) -> dict[str, int]:
        """Particles per variable of ``graph`` (every variable but noise ones) from
        ``num_particles`` (one int for all, or name → int, the others the default)."""
        names = [v.name for v in graph.variables.values() if v.role != "noise"]
        if isinstance(self.num_particles, dict):
            unknown = set(self.num_particles) - set(names)
            if unknown:
                raise ValueError(f"num_particles names unknown variables {sorted(unknown)}")
            counts = {n: self.num_particles.get(n, EngineSettings.num_particles) for n in names}
        else:
            counts = {n: self.num_particles for n in names}
        return {n: int(c) for n, c in counts.items()}  # validated by EngineSettings

    def belief_classes(self) -> dict[str, type]:
        """``beliefs`` as belief classes."""
        return {v: BELIEF_FORMS[form] for v, form in (self.beliefs or {}).items()}

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> EngineSettings:
        """Settings from a ``graph.meta["engine"]`` dict; unknown keys are an error."""
        d = dict(d or {})
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ValueError(f"unknown engine setting(s) {unknown} (known: {sorted(names)})")
        return cls(**d)

    def to_dict(self, full: bool = False) -> dict[str, Any]:
        """JSON-ready dict: ``num_particles`` and the fields that differ from the defaults
        (every field with ``full=True``: what the engine writes into its graph's
        ``meta["engine"]``, so a run's saved ``model.json`` holds every setting it ran
        with)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
               if full or f.name == "num_particles" or getattr(self, f.name) != f.default}
        if callable(out.get("resampling")):
            out["resampling"] = getattr(out["resampling"], "__name__", "custom")
        return out

    def with_beliefs(self, belief_types: dict[str, type] | None) -> EngineSettings:
        """A copy whose ``beliefs`` also name the forms of ``belief_types`` (variable →
        belief class, as ``Engine(belief_types=...)`` takes them), so that a saved model
        holds them; a class of no registered form (:func:`register_belief_form`) is not
        named (it runs, but a reloaded model holds the variable's default belief)."""
        forms = {cls: form for form, cls in BELIEF_FORMS.items()}
        named = {v: forms[c] for v, c in (belief_types or {}).items() if c in forms}
        return self.replace(beliefs={**(self.beliefs or {}), **named}) if named else self

    def replace(self, **changes: Any) -> EngineSettings:
        """A copy with ``changes`` applied (``None`` values are ignored)."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})
