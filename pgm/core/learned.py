"""What a factor learns from the video, kept apart from what declares it.

A factor's parameters (``params()``, saved in a model file) say what it *is*; what it
learns as the video runs — a colour template, a correlation filter, an adaptive offset —
is its *learned state*, a typed dataclass the class declares as ``State``::

    @dataclass
    class TemplateState(LearnedState):
        template: np.ndarray | None = None   # learned in the first frame

    class MyCue(BoxAppearanceLikelihood):
        State = TemplateState

The factor's methods read and write ``self.template`` as before: each field of ``State``
is a descriptor on the class that reads and writes the state object the factor is bound
to (:meth:`pgm.core.factor.Factor.bind`). So one declared factor serves many learners
without being copied: a plate's replicas, or the tracks of an association, each hold
their own state (in the engine's state slots, :class:`pgm.inference.state.StateSlots`)
and a light *view* of the shared factor bound to it.

>>> from dataclasses import dataclass
>>> @dataclass
... class Count(LearnedState):
...     seen: int = 0
>>> a, b = Count(), Count()
>>> a.seen = 3
>>> b.seen
0
"""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

__all__ = ["LearnedState", "StateField", "install_state_fields"]


@dataclasses.dataclass
class LearnedState:
    """Base of a factor's learned state (subclass it as a ``@dataclass``; a field's
    default is its value before the factor learns anything)."""

    def fresh(self) -> LearnedState:
        """An independent copy (a newborn replica's or track's state, taken from the
        declared factor's, which never learns)."""
        return copy.deepcopy(self)


class StateField:
    """A field of a factor's learned state, read and written through the factor (a data
    descriptor: ``factor.template`` is ``factor.state.template``)."""

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        return getattr(obj.__dict__["_state"], self.name)

    def __set__(self, obj: Any, value: Any) -> None:
        setattr(obj.__dict__["_state"], self.name, value)

    def __repr__(self) -> str:
        return f"StateField({self.name!r})"


def install_state_fields(cls: type) -> None:
    """Put a :class:`StateField` on ``cls`` for each field of ``cls.State`` (a dataclass
    deriving from :class:`LearnedState`); a ``ValueError`` names a ``State`` that is not
    one, or a field that would hide a method or class attribute."""
    state = cls.__dict__.get("State")
    if state is None:
        return
    if not (isinstance(state, type) and issubclass(state, LearnedState)
            and dataclasses.is_dataclass(state)):
        raise ValueError(f"{cls.__name__}.State must be a @dataclass deriving from "
                         f"pgm.core.learned.LearnedState, got {state!r}")
    for f in dataclasses.fields(state):
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ValueError(f"{cls.__name__}.State field {f.name!r} needs a default (its "
                             f"value before the factor learns)")
        here = getattr(cls, f.name, None)
        if here is not None and not isinstance(here, StateField):
            raise ValueError(f"{cls.__name__}.State field {f.name!r} hides the class "
                             f"attribute {cls.__name__}.{f.name}")
        setattr(cls, f.name, StateField(f.name))
