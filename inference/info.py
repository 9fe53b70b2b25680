"""What a frame's stages report, typed: the diagnostics of a step record.

A rule returns its diagnostics as one of these dataclasses (or None); the engine keeps
them in :attr:`pgm.inference.record.StepRecord.info` by variable or factor name, and the
plate's own report in :attr:`~pgm.inference.record.StepRecord.plate`. Each field is
named and documented where it is defined; a field left ``None`` was not reported this
frame. An info object also reads as a read-only mapping of its reported fields, so
``record.info["noise"]["elbo"]`` and ``record.info["noise"].elbo`` are the same.

>>> info = VariableInfo(ess=42.0)
>>> info.merge(VariableInfo(resampled=True))
VariableInfo(own_mass=None, resampled=True, ess=42.0, particles=None, degenerate=None, extra={})
>>> sorted(info)
['ess', 'resampled']

A rule of one's own may still return a plain ``dict``: a factor's is kept as it is, a
variable's fuse or resample stage merges its keys into the variable's
:class:`VariableInfo` (those it does not declare into ``extra``).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Info", "VariableInfo", "VBInfo", "AssociationInfo", "DetectionInfo",
           "ProposalInfo", "PlateInfo", "realigned"]


@functools.cache
def _names(cls: type) -> tuple[str, ...]:
    """An info class's field names but ``extra`` (computed once per class)."""
    return tuple(f.name for f in dataclasses.fields(cls) if f.name != "extra")


class Info:
    """Base of the typed diagnostics: a dataclass whose fields left ``None`` were not
    reported, read also as a read-only mapping of those that were (and of ``extra``,
    where a class has it; registered as a :class:`collections.abc.Mapping`, not derived
    from it, so that ``isinstance(x, Info)`` stays a plain class check on the hot path)."""

    def _reported(self) -> dict[str, Any]:
        d = self.__dict__
        out = {n: d[n] for n in _names(type(self)) if d[n] is not None}
        if d.get("extra"):
            out.update(d["extra"])
        return out

    def __getitem__(self, key: str) -> Any:
        d = self.__dict__
        if key in _names(type(self)) and d[key] is not None:
            return d[key]
        extra = d.get("extra")
        if extra and key in extra:
            return extra[key]
        raise KeyError(key)

    def __iter__(self) -> Iterator[str]:
        return iter(self._reported())

    def __len__(self) -> int:
        return len(self._reported())

    def __bool__(self) -> bool:
        d = self.__dict__
        for n in _names(type(self)):
            if d[n] is not None:
                return True
        return bool(d.get("extra"))

    def __contains__(self, key: object) -> bool:
        try:
            self[key]  # type: ignore[index]
        except (KeyError, TypeError):
            return False
        return True

    def get(self, key: str, default: Any = None) -> Any:
        try:
            return self[key]
        except KeyError:
            return default

    def keys(self):
        return self._reported().keys()

    def items(self):
        return self._reported().items()

    def values(self):
        return self._reported().values()

    def merge(self, other: Mapping[str, Any] | None) -> Info:
        """Set the fields ``other`` reports (an info object or a dict; keys this class
        does not declare go to ``extra`` where it has one, else a ``ValueError``);
        returns ``self``."""
        if not other:
            return self
        names = _names(type(self))
        for key, value in other.items():
            if key in names:
                setattr(self, key, value)
            elif hasattr(self, "extra"):
                self.extra[key] = value
            else:
                raise ValueError(f"{type(self).__name__} has no field {key!r} (fields: "
                                 f"{sorted(names)})")
        return self


Mapping.register(Info)


@dataclass(eq=False)
class VariableInfo(Info):
    """What the stages of one variable report in a frame.

    Attributes
    ----------
    own_mass : float or (K,) array
        Particle BP's fuse stage: the share of the fused mixture's weight on the
        variable's own particles (the rest came with messages).
    resampled : bool or (K,) bool array
        The resample stage: whether the belief (each replica's) was resampled.
    ess : float or (K,) array
        The effective sample size the resample stage read.
    particles : int
        A PHD filter's resample stage: the particle budget it resampled to.
    degenerate : (n,) int array
        The weight stage: replicas no particle of which explains the frame (they keep
        their prediction).
    extra : dict
        What a rule of one's own reported beside these.
    """

    own_mass: Any = None
    resampled: Any = None
    ess: Any = None
    particles: int | None = None
    degenerate: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(eq=False)
class VBInfo(Info):
    """A mean-field VB update (a noise belief's fixed point).

    Attributes
    ----------
    iterations : int
        Fixed-point iterations run.
    elbo : list of float
        The evidence lower bound after each iteration (it never decreases).
    r_hat : float or array
        The posterior mean measurement variance (per component).
    tracks : int
        Per-track VB-PHD: the labelled tracks that shared the update.
    r_hat_by_label : dict
        Per-track VB-PHD: each label's posterior mean variance.
    """

    iterations: int | None = None
    elbo: Any = None
    r_hat: Any = None
    tracks: int | None = None
    r_hat_by_label: dict | None = None


@dataclass(eq=False)
class AssociationInfo(Info):
    """The assign stage of an association factor.

    Attributes
    ----------
    matched : (K,) float array
        Per replica, the index of its detection this frame (NaN: none).
    presence : (K,) bool array
        With a round of ``"update": false``: per replica, whether its match was one of
        that round's (kept matched, not updated).
    iterations : int
        VB-SORT: the adaptive Kalman fixed point's iterations (the most over replicas).
    """

    matched: np.ndarray | None = None
    presence: np.ndarray | None = None
    iterations: int | None = None


@dataclass(eq=False)
class DetectionInfo(Info):
    """A detection likelihood on Gaussian beliefs.

    Attributes
    ----------
    reupdated : (n,) int array
        OC-SORT's re-update: the replicas whose state was re-run along the virtual
        trajectory from their last detection.
    hidden_edges : int
        Detections gated out by a coupling's hidden edges.
    """

    reupdated: np.ndarray | None = None
    hidden_edges: int | None = None


@dataclass(eq=False)
class ProposalInfo(Info):
    """A proposal factor's predict rule.

    Attributes
    ----------
    proposed : float
        The share of particles drawn from the proposal (the rest from the transition).
    """

    proposed: float | None = None


@dataclass(eq=False)
class PlateInfo(Info):
    """What a plate reports after its frame (one entry per replica, in replica order).

    Attributes
    ----------
    ids : (K,) int array
        Track identities (0: none yet).
    boxes : (K, 4) array
        The replicas' boxes ``(cx, cy, w, h)`` as reported.
    reported : (K,) bool array
        Which replicas are reported (confirmed and not lost).
    existence : (K,) array
        Each replica's existence score.
    births : int
        Replicas started this frame.
    deaths : (n,) int array
        Identities of the replicas removed this frame (0: never confirmed).
    missing : bool
        The frame had no image, detections or measurements (the replicas coast).
    filled : tuple of arrays, optional
        Rows for earlier frames, reported now (:attr:`~pgm.core.plate.Lifecycle.
        fill_gaps`): frame numbers ``(n,)``, identities ``(n,)``, boxes ``(n, 4)``
        ``(cx, cy, w, h)`` and scores ``(n,)``.
    """

    ids: np.ndarray | None = None
    boxes: np.ndarray | None = None
    reported: np.ndarray | None = None
    existence: np.ndarray | None = None
    births: int | None = None
    deaths: np.ndarray | None = None
    missing: bool | None = None
    filled: tuple | None = None


def realigned(values: Any, keep: np.ndarray, births: int) -> Any:
    """Per-replica diagnostics (arrays with a leading replica axis) after the replicas
    ``keep`` survived and ``births`` were added: survivors' rows, then empty rows (NaN,
    False or 0); replica indices (``degenerate``) renumbered; anything else as it was.
    ``values``: an info object (realigned in place, returned) or a dict (a new one)."""
    if not values:
        return values
    new_index = np.cumsum(keep) - 1

    def one(key: str, a: Any) -> Any:
        if isinstance(a, dict):
            return realigned(a, keep, births)
        if key == "degenerate" and isinstance(a, np.ndarray):
            return np.array([new_index[i] for i in a if keep[i]], dtype=int)
        if isinstance(a, np.ndarray) and a.ndim >= 1 and a.shape[0] == keep.shape[0]:
            fill = False if a.dtype == bool else (np.nan if a.dtype.kind == "f" else 0)
            pad = np.full((births,) + a.shape[1:], fill, dtype=a.dtype)
            return np.concatenate([a[keep], pad])
        return a

    if isinstance(values, Info):
        for key, a in values._reported().items():
            new = one(key, a)
            if key in getattr(values, "extra", {}):
                values.extra[key] = new
            else:
                setattr(values, key, new)
        return values
    return {key: one(key, a) for key, a in values.items()}
