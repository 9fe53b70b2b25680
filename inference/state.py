"""What rules keep across frames, typed: a slot per owner (a variable or a factor name) and
declared class, instead of a dictionary of string keys.

A rule family declares the state it keeps as a dataclass next to its rules
(:class:`~pgm.inference.phd.PHDState`, :class:`~pgm.inference.association.TrackState`,
…); the engine holds one :class:`StateSlots` (``engine.state``) and a plate one per
replica (``engine.replicas.state[k]``), which the plate selects and joins with its
replicas. What one stage hands to another is then a field named where it is defined.

>>> slots = StateSlots()
>>> slots.get("x", ProposalState).prior_log_mass = -1.5
>>> slots.find("x", ProposalState).take()
-1.5
>>> slots.find("x", ProposalState).take() is None
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypeVar

__all__ = ["StateSlots", "ProposalState"]

T = TypeVar("T")


class StateSlots:
    """One state object of each declared class per owner (a variable or factor name)."""

    __slots__ = ("_slots",)

    def __init__(self) -> None:
        self._slots: dict[tuple[str, type], Any] = {}

    def get(self, owner: str, cls: type[T]) -> T:
        """The ``cls`` state of ``owner``, made (``cls()``) at the first call."""
        key = (owner, cls)
        obj = self._slots.get(key)
        if obj is None:
            obj = self._slots[key] = cls()
        return obj

    def hold(self, owner: str, obj: T) -> T:
        """Keep ``obj`` as ``owner``'s state of its class (a factor's learned state, made
        by the factor: :meth:`pgm.core.factor.Factor.fresh_state`); returns it."""
        self._slots[(owner, type(obj))] = obj
        return obj

    def find(self, owner: str, cls: type[T]) -> T | None:
        """The ``cls`` state of ``owner`` if there is one."""
        return self._slots.get((owner, cls))

    def __repr__(self) -> str:
        return "StateSlots(" + ", ".join(f"{o}: {c.__name__}" for o, c in self._slots) + ")"


@dataclass
class ProposalState:
    """A particle variable's state between the predict and weight stages of one frame.

    Attributes
    ----------
    prior_log_mass : float or None
        The belief's log-mass before a proposal factor's weight correction: the mass this
        frame's evidence is measured against (set by the predict rule, taken by the
        weight stage).
    """

    prior_log_mass: Any = None

    def take(self) -> Any:
        """The held mass, cleared (a frame's value is read once)."""
        out, self.prior_log_mass = self.prior_log_mass, None
        return out
