"""Factors: the pieces a tracker is declared from.

A factor has a *scope* (the names of the variables it links) and a *kind* that tells
the engine how inference uses it:

=============== ======================================================================
kind            role in inference
=============== ======================================================================
``prior``       initial belief of a variable (the belief in the first frame)
``transition``  links a variable to its own past values (order 1 or 2)
``likelihood``  links a variable to the current frame / measurements
``coupling``    links two variables in the same frame (parts of one object)
``conjugate``   links a ``noise`` variable to a likelihood it parameterises (VB)
``interaction`` links the replicas of a plate to each other (mutual exclusion, ...)
``proposal``    proposes a variable's next value in place of its transition (SMC)
``association`` assigns the frame's detections to the replicas of a plate (SORT, ...)
=============== ======================================================================

Each factor is a small object with the few vectorised methods the algorithms need
(``sample``, ``log_prob``, ``log_likelihood``, ...); its parameters live on it and are
listed by :meth:`Factor.params`, which is what a saved model declaration stores.
Every concrete factor class registers itself by name when it is defined, so a JSON
declaration is loaded by looking names up in that registry: loading never executes
code. A user's own factor class is registered as soon as its module is imported.

Arrays: particles have a leading particle axis, ``x`` of shape ``(N, d)``.

This module holds the root :class:`Factor` and the registry; the kind base classes and
the generic factors are in :mod:`pgm.factors`.
"""

from __future__ import annotations

import functools
import inspect
from abc import ABC
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from pgm.core.frame import FrameContext
from pgm.core.learned import LearnedState, install_state_fields
from pgm.core.variable import Variable

__all__ = ["Factor", "factor_from_dict", "registered_factor_types", "KINDS", "register_finder",
           "find_names"]

KINDS = ("prior", "transition", "likelihood", "coupling", "conjugate", "interaction",
         "proposal", "association")
_REGISTRY: dict[str, type[Factor]] = {}
#: what makes more names known when a saved graph names a factor type or a readout that is
#: not registered yet (a model file loaded in a fresh process): functions
#: ``finder(found, module)`` that import where it may be defined until ``found()``
#: (``module``: the module the saved declaration names, or None). The layers above the core
#: register them (``pgm/__init__.py``: the toolkit's factor modules, its plate engine and
#: models, installed plug-ins); the core imports nothing by name.
_FINDERS: list[Callable[[Callable[[], bool], str | None], None]] = []


def register_finder(finder: Callable[[Callable[[], bool], str | None], None]) -> None:
    """Add a finder (:data:`_FINDERS`); registering one twice keeps one."""
    if finder not in _FINDERS:
        _FINDERS.append(finder)


def find_names(found: Callable[[], bool], module: str | None = None) -> None:
    """Run the registered finders until ``found()``."""
    for finder in _FINDERS:
        if found():
            return
        finder(found, module)

def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


class Factor(ABC):  # noqa: B024 - kind base classes declare the abstract methods
    """Base class of all factors.

    Subclasses set the class attribute ``kind`` (via one of the kind base classes),
    take their scope's variable names as the first positional arguments and their
    parameters as keyword arguments, and return those keyword arguments from
    :meth:`params` so that ``type(f)(*f.variables, name=f.name, **f.params())``
    rebuilds an equal factor.
    """

    kind: ClassVar[str] = ""
    #: number of variables in the scope (None: any)
    arity: ClassVar[int | None] = 1
    #: what the factor learns from the video, typed (:mod:`pgm.core.learned`): None for a
    #: factor that learns nothing
    State: ClassVar[type[LearnedState] | None] = None

    def __new__(cls, *args: Any, **kwargs: Any) -> Factor:
        obj = super().__new__(cls)
        if cls.State is not None:
            obj.__dict__["_state"] = cls.State()
        return obj

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        install_state_fields(cls)
        if cls.__dict__.get("abstract", False):
            return
        if cls.kind not in KINDS:
            return
        name = cls.__name__
        other = _REGISTRY.get(name)
        if other is not None and other.__module__ != cls.__module__:
            raise ValueError(
                f"factor type {name!r} is defined twice ({other.__module__} and {cls.__module__})")
        _REGISTRY[name] = cls

    def __init__(self, *variables: str, name: str | None = None) -> None:
        if self.arity is not None and len(variables) != self.arity:
            raise ValueError(
                f"{type(self).__name__} links {self.arity} variable(s), got {len(variables)}: "
                f"{variables}")
        for v in variables:
            if isinstance(v, Variable):
                raise ValueError(f"{type(self).__name__}: give variable names, not objects "
                                 f"(use {v.name!r})")
            if not isinstance(v, str) or not v:
                raise ValueError(f"{type(self).__name__}: variable names must be strings, got {v!r}")
        self.variables: tuple[str, ...] = tuple(variables)
        #: True when the name was made up here (a graph may then disambiguate it)
        self.auto_named = name is None
        self.name = name if name is not None else f"{self.kind}:{'-'.join(variables)}"

    # -- declaration -----------------------------------------------------------------
    def params(self) -> dict[str, Any]:
        """Keyword arguments that rebuild this factor (JSON-ready after conversion)."""
        return {}

    def check(self, variables: dict[str, Variable]) -> None:  # noqa: B027 - optional hook
        """Validate against the graph's variables; raise ``ValueError`` naming the factor."""

    def _check_dim(self, variables: dict[str, Variable], var: str, expected: int, what: str):
        if variables[var].dim != expected:
            raise ValueError(f"factor {self.name!r}: {what} has dimension {expected} but variable "
                             f"{var!r} has dim {variables[var].dim}")

    # -- learned state -----------------------------------------------------------------
    @property
    def state(self) -> LearnedState | None:
        """The learned state this factor reads and writes (None: it learns nothing)."""
        return self.__dict__.get("_state")

    def fresh_state(self) -> LearnedState | None:
        """An independent copy of :attr:`state` (for a new learner: a replica, a track)."""
        st = self.state
        return None if st is None else st.fresh()

    def bind(self, state: LearnedState | None) -> Factor:
        """A view of this factor that learns into ``state``: the declaration (every
        attribute but the learned state) is shared, not copied. ``state`` must be of the
        class's ``State`` (a factor without one is returned as it is)."""
        if type(self).State is None:
            return self
        if not isinstance(state, type(self).State):
            raise ValueError(f"factor {self.name!r}: bind() needs a "
                             f"{type(self).State.__name__}, got {type(state).__name__}")
        view = object.__new__(type(self))
        view.__dict__.update(self.__dict__)
        view.__dict__["_state"] = state
        return view

    @property
    def learns(self) -> bool:
        """Whether :meth:`update` does anything (the engine skips the scores otherwise)."""
        return type(self).update is not Factor.update

    def update(self, estimates: dict[str, np.ndarray], scores: dict[str, float],  # noqa: B027
               frame: FrameContext | None = None) -> None:
        """Learn after a frame (adaptive offsets, templates, ...); default: nothing.

        ``estimates`` are the frame's per-variable estimates; ``scores`` the summed
        log-likelihood of each variable's likelihood factors at its estimate; ``frame``
        the frame itself. The engine calls it only for factors whose :attr:`learns` is
        true.
        """

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready declaration ``{"type", "module", "name", "kind", "variables",
        "params"}`` (``module``: where the type is defined, which a loader may import if it
        is the toolkit's or an installed plug-in's). A type whose ``__init__`` takes
        parameters that no :meth:`params` of its own returns is warned about (once): the
        declaration would rebuild it with their defaults."""
        unsaved = _unsaved_parameters(type(self), len(self.variables))
        if unsaved and type(self) not in _WARNED_UNSAVED:
            import warnings

            _WARNED_UNSAVED.add(type(self))
            warnings.warn(f"factor {self.name!r}: {type(self).__name__}.__init__ takes "
                          f"{', '.join(unsaved)}, which no params() of it returns: a saved "
                          f"model rebuilds it with their defaults (define params(), "
                          f"docs/developing.md)", UserWarning, stacklevel=2)
        return {"type": type(self).__name__, "module": type(self).__module__,
                "name": self.name, "kind": self.kind, "variables": list(self.variables),
                "params": _jsonable(self.params())}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(self.variables)}, name={self.name!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Factor):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = object.__hash__


#: factor types already warned about by :meth:`Factor.to_dict`
_WARNED_UNSAVED: set[type] = set()


@functools.lru_cache(maxsize=None)
def _unsaved_parameters(cls: type, n_variables: int) -> tuple[str, ...]:
    """The parameters of ``cls.__init__`` (beyond its variables and ``name``) that its
    declaration cannot carry: those of a type whose only :meth:`Factor.params` is the
    base's (which returns none)."""
    if next(c for c in cls.__mro__ if "params" in c.__dict__) is not Factor:
        return ()
    init = next(c for c in cls.__mro__ if "__init__" in c.__dict__).__init__
    if init is Factor.__init__:
        return ()
    kinds = inspect.Parameter
    params = list(inspect.signature(init).parameters.values())[1:]  # after self
    positional = [p for p in params if p.kind in (kinds.POSITIONAL_ONLY,
                                                  kinds.POSITIONAL_OR_KEYWORD)]
    variables = {p.name for p in positional[:n_variables]}
    return tuple(p.name for p in params if p.name not in variables and p.name != "name"
                 and p.kind not in (kinds.VAR_POSITIONAL, kinds.VAR_KEYWORD))


def factor_from_dict(d: dict[str, Any]) -> Factor:
    """Rebuild a factor from :meth:`Factor.to_dict` output (a registry lookup, no code)."""
    try:
        type_name = d["type"]
        variables = d["variables"]
    except (KeyError, TypeError) as exc:
        raise ValueError(f"malformed factor declaration {d!r}: missing {exc}") from None
    cls = _REGISTRY.get(type_name)
    if cls is None and isinstance(type_name, str):
        module = d.get("module")
        find_names(lambda: type_name in _REGISTRY, module if isinstance(module, str) else None)
        cls = _REGISTRY.get(type_name)
    if cls is None:
        where = f" ({d['module']})" if isinstance(d.get("module"), str) else ""
        raise ValueError(
            f"unknown factor type {type_name!r}{where}: import the module that defines it "
            f"before loading (on the command line: --import MODULE_OR_FILE; known: "
            f"{sorted(_REGISTRY)})")
    try:
        return cls(*variables, name=d.get("name"), **d.get("params", {}))
    except TypeError as exc:
        raise ValueError(f"factor {d.get('name')!r} of type {type_name}: {exc}") from None


def registered_factor_types() -> dict[str, type[Factor]]:
    """Name → class of every registered factor type."""
    return dict(_REGISTRY)
