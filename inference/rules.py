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
           "GROUP_SCORING", "scores_in_groups", "register_replica_adapter"]

#: operations on one variable's belief (rules keyed by name, not by a factor class)
BELIEF_OPERATIONS = ("fuse", "resample", "estimate")

Rule = Callable[..., Any]


def likelihood_reweights(belief_type: type) -> bool:
    """Whether likelihood factors act on ``belief_type`` by reweighting (the contract)."""
    return bool(getattr(belief_type, "likelihood_reweights", False))


#: likelihood rules whose factors the engine may score in one pass, by kind: ``"graph"``
#: (several factors of one graph on one variable, ``log_likelihood_batch``) or
#: ``"replicas"`` (a plate's copies of factors); a rule wrapped by another function
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


def register_replica_adapter(adapter: Callable[[Rule, Any], Rule]) -> None:
    """Set how a replica's rule runs on a batched belief (``adapter(rule, key)``)."""
    global _REPLICA_ADAPTER
    _REPLICA_ADAPTER = adapter


def _key_name(key: type | str) -> str:
    return key if isinstance(key, str) else key.__name__


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
            for b in belief_type.__mro__:
                rule = self._rules.get((k, b))
                if rule is not None:
                    return rule
            if row_type is not None:  # a batched belief: the replica's rule, per replica
                for b in row_type.__mro__:
                    rule = self._rules.get((k, b))
                    if rule is not None:
                        if _REPLICA_ADAPTER is None:  # pragma: no cover - set on import
                            raise RuntimeError("no replica adapter registered: import "
                                               "pgm.inference")
                        return _REPLICA_ADAPTER(rule, key)
        return None

    def lookup(self, key: type | str, belief_type: type) -> Rule:
        """The rule for ``key`` (a factor class or a belief operation) on ``belief_type``."""
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
