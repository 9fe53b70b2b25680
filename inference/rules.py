"""The rule table: inference rules keyed by *(factor class, belief type)*.

Dispatch is by *(factor class, belief type)* — as ReactiveMP keys rules by node and edge —
each resolved along its MRO (the factor's first, then the belief's), so
``rules.register(MyLikelihood, Particles)`` gives a user's factor its own rule and a
subclass (e.g. :class:`~pgm.Intensity`) inherits rules it does not override. Belief
operations (``fuse``, ``resample``, ``estimate``) are keyed by *(operation, belief type)*.

**Batched beliefs.** A plate's variables hold batched beliefs (:mod:`pgm.core.batched`),
each naming the single-graph type of one replica as ``row_type``. A lookup on a batched
type takes, at each class of the factor's MRO, a rule registered for the batched type
itself (a vectorised rule) or else one registered for its ``row_type``, run once per
replica (:func:`pgm.inference.plates.per_replica`). So a user's rule
``register(MyLikelihood, Particles)`` runs inside a plate too, and every single-graph
rule (VB, product fusion, exact Gaussian rules) serves a plate without a batched twin.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pgm.core.factor import Factor

__all__ = ["RuleTable", "DEFAULT_RULES", "BELIEF_OPERATIONS", "Rule", "likelihood_reweights",
           "GROUP_SCORING", "scores_in_groups", "register_replica_adapter", "declare",
           "rule_name", "find_rule", "saved_rules", "use_rules", "per_replica", "PER_REPLICA"]

#: operations on one variable's belief (rules keyed by name, not by a factor class)
BELIEF_OPERATIONS = ("fuse", "resample", "estimate")

Rule = Callable[..., Any]


def likelihood_reweights(belief_type: type) -> bool:
    """Whether likelihood factors act on ``belief_type`` by reweighting (the contract)."""
    return bool(getattr(belief_type, "likelihood_reweights", False))


#: likelihood rules whose factors the engine may score in one pass, by kind: ``"graph"``
#: (several factors of one graph on one variable, ``log_likelihood_batch``) or
#: ``"replicas"`` (a plate's per-replica views of factors); a rule wrapped by another function
#: (:func:`pgm.inference.conformance.checked`) is scored one factor at a time
GROUP_SCORING: dict[Rule, str] = {}


def scores_in_groups(kind: str) -> Callable[[Rule], Rule]:
    """Decorator: the engine may score the factors of this likelihood rule in groups
    (:data:`GROUP_SCORING`)."""
    if kind not in ("graph", "replicas"):
        raise ValueError(f"kind must be 'graph' or 'replicas', got {kind!r}")

    def deco(rule: Rule) -> Rule:
        GROUP_SCORING[rule] = kind
        return rule

    return deco


#: how a single-graph rule runs once per replica of a plate (the batched rules' module,
#: :func:`pgm.inference.batched.per_replica`, registers it: this table imports no family)
_REPLICA_ADAPTER: Callable[[Rule, Any], Rule] | None = None


def per_replica(rule: Rule, key: type | str) -> Rule:
    """``rule`` (a single-graph rule) run once per replica of a plate (the adapter the
    batched rules' module registers)."""
    if _REPLICA_ADAPTER is None:  # pragma: no cover - set on import of pgm.inference
        raise RuntimeError("no replica adapter registered: import pgm.inference")
    return _REPLICA_ADAPTER(rule, key)


def register_replica_adapter(adapter: Callable[[Rule, Any], Rule]) -> None:
    """Set how a replica's rule runs on a batched belief (``adapter(rule, key)``)."""
    global _REPLICA_ADAPTER
    _REPLICA_ADAPTER = adapter


def _key_name(key: type | str) -> str:
    return key if isinstance(key, str) else key.__name__


# -------------------------------------------------------------------------------------
# rules that travel with their factor class and with a saved model
# -------------------------------------------------------------------------------------
def declare(factor_class: type, belief_type: type) -> Callable[[Rule], Rule]:
    """Decorator: ``factor_class``'s own rule on ``belief_type``, declared where the class
    is defined (``factor_class.declared_rules``). Every :class:`RuleTable` finds it (at the
    class's place in the factor's MRO, after a rule a table registers for that same
    class), so the rule goes wherever the factor goes: a graph built anywhere, a saved
    model reloaded in another process once the class's module is imported.

    >>> from pgm.core.beliefs import Particles
    >>> from pgm.factors import LikelihoodFactor
    >>> class Flat(LikelihoodFactor):
    ...     def log_likelihood(self, x, frame):
    ...         return x[:, 0] * 0.0
    >>> @declare(Flat, Particles)
    ... def flat_rule(ctx, factor, frame):
    ...     return factor.log_likelihood(ctx.beliefs[factor.variables[0]].x, frame)
    >>> RuleTable().lookup(Flat, Particles) is flat_rule
    True
    """
    RuleTable._check_key(factor_class, belief_type)
    if isinstance(factor_class, str):
        raise ValueError("declare() takes a factor class; register belief operations in a "
                         "RuleTable")

    def deco(rule: Rule) -> Rule:
        own = factor_class.__dict__.get("declared_rules")
        if own is None:  # the class's own table, not one inherited from its base
            own = {}
            factor_class.declared_rules = own
        own[belief_type] = rule
        _DECLARED_VERSION[0] += 1
        return rule

    return deco


#: bumped by :func:`declare` so that tables drop lookups resolved before it
_DECLARED_VERSION = [0]
#: the mark of a rule run once per replica of a plate in a saved rule name
PER_REPLICA = " [per replica]"


def use_rules(graph: Any, rules: dict[str, Rule]) -> Any:
    """``graph`` with ``rules`` (factor name → rule) recorded as the rules that serve those
    factors (``graph.meta["rules"]``): an :class:`~pgm.inference.Engine` given no table
    runs them, and the graph saves them by name — how a model config attaches a rule of
    its own to a factor without touching :data:`DEFAULT_RULES`. Each rule must be
    findable by name (defined at module level). Returns the graph (changed in place)."""
    named = dict(graph.meta.get("rules") or {})
    for factor, rule in rules.items():
        if factor not in graph.factors:
            raise ValueError(f"use_rules: graph {graph.name!r} has no factor {factor!r}")
        name = rule_name(rule)
        found, _ = find_rule(name, f"factor {factor!r}")
        if found is not rule and getattr(rule, "row_rule", None) is None:
            raise ValueError(f"factor {factor!r}: rule {name!r} does not name the function "
                             f"given (define it at module level)")
        named[factor] = name
    graph.meta["rules"] = named
    return graph


def saved_rules(graph: Any) -> dict[str, tuple[Rule, bool]]:
    """The rules a saved model names per factor (``graph.meta["rules"]``), found by name
    (:func:`find_rule`): factor name → ``(rule, runs once per replica)``."""
    saved = graph.meta.get("rules")
    if not saved:
        return {}
    if not isinstance(saved, dict):
        raise ValueError(f"graph {graph.name!r}: meta['rules'] must map factor names to rule "
                         f"names, got {type(saved).__name__}")
    out = {}
    for name, rule in saved.items():
        if name not in graph.factors:
            raise ValueError(f"graph {graph.name!r}: meta['rules'] names unknown factor "
                             f"{name!r}")
        out[name] = find_rule(rule, f"factor {name!r}")
    return out


def rule_name(rule: Rule) -> str:
    """The importable name ``"module:qualname"`` of ``rule`` (a plate's per-replica run of
    a single-graph rule is named by that rule, marked :data:`PER_REPLICA`)."""
    row = getattr(rule, "row_rule", None)
    if row is not None:
        return rule_name(row) + PER_REPLICA
    return f"{getattr(rule, '__module__', '?')}:{getattr(rule, '__qualname__', repr(rule))}"


def find_rule(name: str, what: str) -> tuple[Rule, bool]:
    """The rule a saved model names (``"module:qualname"``, :func:`rule_name`) and whether
    it runs once per replica; a ``ValueError`` of one line naming it and ``what`` (the
    factor) where it cannot be found. Only a module already imported or one of the
    toolkit's is looked in: loading a model runs no code of its own (a user's rules are
    imported by the user, ``pgm track --import MODULE_OR_FILE``)."""
    import importlib
    import sys

    if not isinstance(name, str) or ":" not in name:
        raise ValueError(f"{what}: saved rule {name!r} is not a 'module:function' name")
    per_replica = name.endswith(PER_REPLICA)
    base = name[:-len(PER_REPLICA)] if per_replica else name
    module_name, _, qualname = base.partition(":")
    module = sys.modules.get(module_name)
    if module is None and (module_name == "pgm" or module_name.startswith("pgm.")):
        try:
            module = importlib.import_module(module_name)
        except ImportError:
            module = None
    if module is None:
        raise ValueError(f"{what}: its rule {base!r} cannot be found: module {module_name!r} "
                         f"is not imported (import it first; on the command line: --import "
                         f"MODULE_OR_FILE)")
    if "<locals>" in qualname:
        raise ValueError(f"{what}: its rule {base!r} was defined inside a function and cannot "
                         f"be loaded; define it at module level to save a model that uses it")
    obj: Any = module
    for part in qualname.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise ValueError(f"{what}: its rule {base!r} cannot be found: {module_name!r} has "
                             f"no {qualname!r}")
    if not callable(obj):
        raise ValueError(f"{what}: saved rule {base!r} is not callable")
    return obj, per_replica


class RuleTable:
    """Inference rules keyed by ``(factor class, belief type)`` or ``(operation, belief type)``.

    Factor rules are looked up along the factor class's MRO first, then the belief
    type's: ``register(PHDLikelihood, Intensity)`` wins over ``register(LikelihoodFactor,
    Intensity)`` for a PHD factor, and both over ``(LikelihoodFactor, Particles)``.

    Calling conventions
    -------------------
    A rule receives a :class:`~pgm.inference.context.RuleContext` ``ctx`` (the beliefs,
    this frame's evidence and messages, the generator, the settings, its state slots),
    never the engine:

    * prior, transition, conjugate factors: ``rule(ctx, factor, frame)``; updates
      ``ctx.beliefs``; may return a dict of diagnostics;
    * likelihood factors on a belief that likelihoods reweight (:class:`~pgm.Particles`):
      ``rule(ctx, factor, frame) -> log_lik`` of shape ``(N,)``, touching no belief;
      on other beliefs, as a prior rule;
    * coupling factors: ``rule(ctx, factor, frame, src, dst)`` (one directed message);
    * belief operations (``fuse``, ``resample``, ``estimate``):
      ``rule(ctx, variable_name, frame)``.

    Diagnostics are stored in the step record under the factor's (or variable's) name.
    """

    def __init__(self, rules: dict[tuple[type | str, type], Rule] | None = None):
        self._rules: dict[tuple[type | str, type], Rule] = dict(rules or {})
        self._resolved: dict[tuple[type | str, type], Rule] = {}
        self._declared_version = _DECLARED_VERSION[0]

    @staticmethod
    def _check_key(key: type | str, belief_type: type) -> None:
        if isinstance(key, str):
            if key not in BELIEF_OPERATIONS:
                raise ValueError(f"unknown operation {key!r}: register a factor class, or one "
                                 f"of {BELIEF_OPERATIONS}")
        elif not (isinstance(key, type) and issubclass(key, Factor)):
            raise ValueError(f"rule key must be a Factor subclass or one of "
                             f"{BELIEF_OPERATIONS}, got {key!r}")
        if not isinstance(belief_type, type):
            raise ValueError(f"belief type must be a class, got {belief_type!r}")

    def register(self, key: type | str, belief_type: type) -> Callable[[Rule], Rule]:
        """Decorator registering a rule for ``(factor class | operation, belief type)``."""
        self._check_key(key, belief_type)

        def deco(rule: Rule) -> Rule:
            self._rules[(key, belief_type)] = rule
            self._resolved.clear()
            return rule

        return deco

    def _find(self, key: type | str, belief_type: type) -> Rule | None:
        keys = [key] if isinstance(key, str) else [
            k for k in key.__mro__ if isinstance(k, type) and issubclass(k, Factor)]
        row_type = getattr(belief_type, "row_type", None)
        for k in keys:
            declared = () if isinstance(k, str) else k.__dict__.get("declared_rules", {})
            for b in belief_type.__mro__:
                rule = self._rules.get((k, b)) or (declared.get(b) if declared else None)
                if rule is not None:
                    return rule
            if row_type is not None:  # a batched belief: the replica's rule, per replica
                for b in row_type.__mro__:
                    rule = self._rules.get((k, b)) or (declared.get(b) if declared else None)
                    if rule is not None:
                        if _REPLICA_ADAPTER is None:  # pragma: no cover - set on import
                            raise RuntimeError("no replica adapter registered: import "
                                               "pgm.inference")
                        return _REPLICA_ADAPTER(rule, key)
        return None

    def lookup(self, key: type | str, belief_type: type) -> Rule:
        """The rule for ``key`` (a factor class or a belief operation) on ``belief_type``."""
        if self._declared_version != _DECLARED_VERSION[0]:
            self._resolved.clear()
            self._declared_version = _DECLARED_VERSION[0]
        hit = self._resolved.get((key, belief_type))
        if hit is not None:
            return hit
        rule = self._find(key, belief_type)
        if rule is None:
            raise ValueError(f"no inference rule for ({_key_name(key)}, {belief_type.__name__}):"
                             f" register one with RuleTable.register")
        self._resolved[(key, belief_type)] = rule
        return rule

    def has(self, key: type | str, belief_type: type) -> bool:
        """Whether :meth:`lookup` would succeed."""
        return self._find(key, belief_type) is not None

    def remove(self, key: type | str, belief_type: type) -> None:
        """Drop the rule registered exactly for ``(key, belief_type)``."""
        self._rules.pop((key, belief_type), None)
        self._resolved.clear()

    def items(self) -> list[tuple[tuple[type | str, type], Rule]]:
        """Every registered ``((key, belief type), rule)`` pair."""
        return list(self._rules.items())

    def update(self, other: RuleTable) -> None:
        """Add ``other``'s rules (they replace rules registered for the same keys)."""
        self._rules.update(other._rules)
        self._resolved.clear()

    def copy(self) -> RuleTable:
        """An independent copy (to add rules for one engine only)."""
        return RuleTable(self._rules)

    def __repr__(self) -> str:
        keys = ", ".join(f"({_key_name(k)}, {t.__name__})" for k, t in self._rules)
        return f"RuleTable([{keys}])"


DEFAULT_RULES = RuleTable()
