"""Error types.

Every problem with user input (a file, a box, a parameter) is raised as
:class:`InputError`, a subclass of :class:`ValueError` whose message is one line
naming the problem. The CLI turns it into ``pgm: error: <message>`` and exit code 2.
"""

from __future__ import annotations

__all__ = ["InputError", "DegenerateWeightsError", "RuleContractError"]


class InputError(ValueError):
    """Bad user input: a missing or corrupt file, a malformed box, a bad parameter."""


class DegenerateWeightsError(ValueError):
    """Every particle weight is zero (all log-weights are -inf or NaN)."""


class RuleContractError(RuntimeError):
    """An inference rule broke its contract (e.g. a likelihood rule moved particles).

    A programming error in a rule, not bad input: it names the rule and the factor.
    """
