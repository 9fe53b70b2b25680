"""Factor graphs held in networkx.

A :class:`FactorGraph` *wraps* (does not subclass) a bipartite ``networkx.Graph``
whose nodes are variable names (``bipartite=0``) and factor names (``bipartite=1``);
an edge joins a factor to each variable of its scope. The graph is the data
structure the engine derives its schedule from, not a picture of it.

It validates on construction — a factor naming an unknown variable, a dimension
mismatch, a coupling between a variable and itself, a ``noise`` variable with no
conjugate factor, a particle variable with no prior — each a ``ValueError`` naming the
offending node. It draws itself in factor-graph notation (:mod:`pgm.plotting.graph_drawing`) and
saves to / loads from JSON without executing code.

Example
-------
>>> from pgm import Variable, FactorGraph, GaussianPrior, LinearGaussianTransition
>>> g = FactorGraph([Variable("x", 1)],
...                 [GaussianPrior("x", mean=[0.0], cov=1.0),
...                  LinearGaussianTransition("x", F=[[1.0]], Q=0.1)])
>>> g.factors_of("x", kind="transition")[0].name
'transition:x'
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import networkx as nx

from pgm.core.factor import Factor, factor_from_dict
from pgm.core.plate import Plate
from pgm.core.variable import Variable

__all__ = ["FactorGraph"]

FORMAT_VERSION = 1


#: how a graph draws itself: ``{"draw": ..., "to_dot": ...}``, registered by the layer that
#: can draw (``pgm/__init__.py``: :mod:`pgm.plotting.graph_drawing`); the core imports no
#: plotting
_DRAWING: dict[str, Any] = {}


def register_drawing(draw: Any, to_dot: Any) -> None:
    """Give graphs their drawing functions (``draw(graph, path, ax, **kw)``,
    ``to_dot(graph)``)."""
    _DRAWING.update(draw=draw, to_dot=to_dot)


def _drawing(name: str) -> Any:
    if name not in _DRAWING:  # pragma: no cover - pgm registers it on import
        raise RuntimeError("no graph drawing registered: import pgm")
    return _DRAWING[name]


class FactorGraph:
    """Variables and factors of a tracker, validated.

    Parameters
    ----------
    variables : iterable of Variable
    factors : iterable of Factor
    name : str
        Model name (e.g. ``"colour-pf"``).
    meta : dict, optional
        JSON-ready extra information: which variable is the tracker's output
        (``meta["output"]``), suggested engine settings (``meta["engine"]``), ...
    plates : iterable of Plate, optional
        Sub-graphs replicated once per target (:mod:`pgm.core.plate`); the engine keeps a
        plate's beliefs batched along a target axis. At most one plate.
    """

    def __init__(self, variables: Iterable[Variable], factors: Iterable[Factor],
                 name: str = "model", meta: dict[str, Any] | None = None,
                 plates: Iterable[Plate] = ()):
        self.name = str(name)
        self.meta: dict[str, Any] = dict(meta or {})
        self.plates: tuple[Plate, ...] = tuple(plates)
        self.variables: dict[str, Variable] = {}
        for v in variables:
            if not isinstance(v, Variable):
                raise ValueError(f"graph {self.name!r}: {v!r} is not a Variable")
            if v.name in self.variables:
                raise ValueError(f"graph {self.name!r}: variable {v.name!r} is declared twice")
            self.variables[v.name] = v
        self.factors: dict[str, Factor] = {}
        for f in factors:
            if not isinstance(f, Factor):
                raise ValueError(f"graph {self.name!r}: {f!r} is not a Factor")
            if f.name in self.factors and getattr(f, "auto_named", False):
                # a second unnamed factor of the same kind on the same variables (e.g.
                # two likelihoods that multiply): name it after its type
                base, k = f"{f.name}:{type(f).__name__}", 2
                f.name = base
                while f.name in self.factors:
                    f.name = f"{base}{k}"
                    k += 1
            if f.name in self.factors:
                raise ValueError(f"graph {self.name!r}: factor name {f.name!r} is used twice")
            if f.name in self.variables:
                raise ValueError(f"graph {self.name!r}: factor {f.name!r} has the name of a "
                                 f"variable")
            self.factors[f.name] = f
        self.nx = nx.Graph(name=self.name)
        for v in self.variables.values():
            self.nx.add_node(v.name, bipartite=0, role=v.role, dim=v.dim)
        for f in self.factors.values():
            self.nx.add_node(f.name, bipartite=1, kind=f.kind, type=type(f).__name__)
            for var in f.variables:
                if var not in self.variables:
                    raise ValueError(f"factor {f.name!r} names unknown variable {var!r} "
                                     f"(declared: {sorted(self.variables)})")
                self.nx.add_edge(f.name, var)
        self._check_plates()
        self.validate()

    def _check_plates(self) -> None:
        for p in self.plates:
            if not isinstance(p, Plate):
                raise ValueError(f"graph {self.name!r}: {p!r} is not a Plate")
        if len(self.plates) > 1:
            raise ValueError(f"graph {self.name!r}: {len(self.plates)} plates declared; one "
                             f"plate per graph is supported")
        inside = self.plate_variables
        for p in self.plates:
            for v in p.variables:
                if v not in self.variables:
                    raise ValueError(f"plate {p.name!r} names unknown variable {v!r} "
                                     f"(declared: {sorted(self.variables)})")
        for f in self.factors.values():
            n_in = sum(v in inside for v in f.variables)
            if f.kind == "interaction" and n_in != len(f.variables):
                raise ValueError(f"interaction factor {f.name!r} links replicas of a plate, "
                                 f"but {[v for v in f.variables if v not in inside]} is in "
                                 f"no plate")
            if 0 < n_in < len(f.variables):
                raise ValueError(
                    f"factor {f.name!r} links variables inside the plate with "
                    f"{[v for v in f.variables if v not in inside]} outside it; parameters "
                    f"shared by every replica belong in the factor's parameters")

    @property
    def plate_variables(self) -> set[str]:
        """Names of the variables inside a plate."""
        return {v for p in self.plates for v in p.variables}

    # -- validation --------------------------------------------------------------------
    def validate(self) -> None:
        """Check the declaration; raise ``ValueError`` naming the offending node."""
        for f in self.factors.values():
            f.check(self.variables)
        for v in self.variables.values():
            priors = self.factors_of(v.name, "prior")
            transitions = [f for f in self.factors_of(v.name, "transition")]
            if len(transitions) > 1:
                raise ValueError(f"variable {v.name!r} has {len(transitions)} transition factors "
                                 f"({[f.name for f in transitions]}); at most one is allowed")
            if len(priors) > 1:
                raise ValueError(f"variable {v.name!r} has {len(priors)} prior factors")
            if v.role == "noise":
                if not any(f.variables[0] == v.name for f in self.factors_of(v.name, "conjugate")):
                    raise ValueError(f"noise variable {v.name!r} has no conjugate factor linking "
                                     f"it to a likelihood")
            elif not priors:
                raise ValueError(f"variable {v.name!r} has no prior factor")
        out = self.meta.get("output")
        if out is not None:
            names = [out] if isinstance(out, str) else list(out)
            for n in names:
                if n not in self.variables:
                    raise ValueError(f"graph {self.name!r}: output variable {n!r} is not declared")

    # -- queries -----------------------------------------------------------------------
    def factors_of(self, variable: str, kind: str | None = None) -> list[Factor]:
        """Factors whose scope contains ``variable`` (optionally of one kind), in order."""
        if variable not in self.variables:
            raise ValueError(f"graph {self.name!r} has no variable {variable!r}")
        return [f for f in self.factors.values()
                if variable in f.variables and (kind is None or f.kind == kind)]

    def factors_by_kind(self, kind: str) -> list[Factor]:
        """All factors of one kind, in declaration order."""
        return [f for f in self.factors.values() if f.kind == kind]

    def neighbours(self, variable: str) -> list[str]:
        """Variables sharing a factor with ``variable``."""
        out: list[str] = []
        for f in self.factors_of(variable):
            out.extend(v for v in f.variables if v != variable and v not in out)
        return out

    @property
    def multi_target(self) -> bool:
        """Whether the graph tracks many targets: a plate (one sub-graph per target) or a
        ``set`` variable (one intensity for all)."""
        return bool(self.plates) or any(v.role == "set" for v in self.variables.values())

    @property
    def output(self) -> list[str]:
        """Names of the variables a tracker reports (``meta["output"]``, else all parts)."""
        out = self.meta.get("output")
        if out is None:
            return [v.name for v in self.variables.values() if v.role == "part"]
        return [out] if isinstance(out, str) else list(out)

    def with_factors(self, *factors: Factor, name: str | None = None) -> FactorGraph:
        """A new graph with ``factors`` added (validated like any graph), e.g. one more
        appearance likelihood on an existing model. The factors are shared, not copied."""
        return type(self)(list(self.variables.values()), list(self.factors.values())
                          + list(factors), name=name or self.name, meta=self.meta,
                          plates=self.plates)

    def __repr__(self) -> str:
        kinds = {}
        for f in self.factors.values():
            kinds[f.kind] = kinds.get(f.kind, 0) + 1
        plates = "".join(f", plate {p.name!r}[{p.size_label}]={list(p.variables)}"
                         for p in self.plates)
        return (f"FactorGraph({self.name!r}, variables={list(self.variables)}, "
                f"factors={kinds}{plates})")

    # -- serialisation -----------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready declaration with every factor's parameters. A rule named in
        ``meta["rules"]`` that another process could not find (defined in the running
        script, ``__main__``, or inside a function) is warned about, once."""
        _warn_unloadable_rules(self)
        d = {"format": "pgm-factor-graph", "version": FORMAT_VERSION, "name": self.name,
             "meta": self.meta,
             "variables": [v.to_dict() for v in self.variables.values()],
             "factors": [f.to_dict() for f in self.factors.values()]}
        if self.plates:
            d["plates"] = [p.to_dict() for p in self.plates]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FactorGraph:
        """Rebuild a graph from :meth:`to_dict` output (registry lookups only)."""
        if not isinstance(d, dict) or d.get("format") != "pgm-factor-graph":
            raise ValueError("not a pgm factor-graph declaration (missing format tag)")
        if d.get("version") != FORMAT_VERSION:
            raise ValueError(f"unsupported declaration version {d.get('version')!r}")
        for key, required in (("variables", True), ("factors", True), ("plates", False)):
            if key not in d and not required:
                continue
            if not isinstance(d.get(key), list) and not (key == "plates" and d[key] is None):
                raise ValueError(f"malformed factor-graph declaration: {key!r} must be a list, "
                                 f"got {type(d.get(key)).__name__}")
        if d.get("meta") is not None and not isinstance(d["meta"], dict):
            raise ValueError(f"malformed factor-graph declaration: 'meta' must be an object, "
                             f"got {type(d['meta']).__name__}")
        try:
            variables = [Variable.from_dict(v) for v in d["variables"]]
            factors = [factor_from_dict(f) for f in d["factors"]]
            plates = [Plate.from_dict(p) for p in d.get("plates") or []]
        except (KeyError, TypeError) as exc:
            raise ValueError(f"malformed factor-graph declaration: {exc}") from None
        return cls(variables, factors, name=d.get("name", "model"), meta=d.get("meta"),
                   plates=plates)

    def save(self, path: str | Path) -> None:
        """Write the declaration with its parameters to a JSON file."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path: str | Path) -> FactorGraph:
        """Load a declaration saved by :meth:`save` (plain JSON: never executes code)."""
        p = Path(path)
        if not p.is_file():
            raise ValueError(f"model file not found: {p}")
        try:
            d = json.loads(p.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"model file {p} is not valid JSON: {exc}") from None
        return cls.from_dict(d)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FactorGraph):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = object.__hash__

    # -- drawing -----------------------------------------------------------------------
    def to_dot(self) -> str:
        """Graphviz DOT text in factor-graph notation (the registered drawing's)."""
        return _drawing("to_dot")(self)

    def draw(self, path: str | Path | None = None, ax=None, **kwargs: Any):
        """Draw the graph with matplotlib; write PNG/SVG/PDF (or DOT) when ``path`` is given
        (:mod:`pgm.plotting.graph_drawing`, registered by ``pgm``)."""
        return _drawing("draw")(self, path=path, ax=ax, **kwargs)


#: rules already warned about by :func:`_warn_unloadable_rules`
_WARNED_RULES: set[str] = set()


def _warn_unloadable_rules(graph: FactorGraph) -> None:
    """Warn (once per rule) where ``graph.meta["rules"]`` names a rule that a saved model
    could not be run with elsewhere: one of the running script's (``__main__``: found only
    where that script has run) or one defined inside a function (never found)."""
    rules = graph.meta.get("rules") if isinstance(graph.meta, dict) else None
    if not isinstance(rules, dict):
        return
    import warnings

    for factor, rule in rules.items():
        if not isinstance(rule, str) or rule in _WARNED_RULES:
            continue
        module, _, qualname = rule.partition(":")
        if "<locals>" in qualname:
            why = "is defined inside a function: a saved model naming it cannot be loaded"
        elif module == "__main__":
            why = ("is defined in the running script: a saved model naming it loads only where "
                   "that script has run")
        else:
            continue
        _WARNED_RULES.add(rule)
        warnings.warn(f"factor {factor!r}: its rule {rule!r} {why} (define it at module level "
                      f"in a module of its own, loaded with --import)", UserWarning, stacklevel=3)
