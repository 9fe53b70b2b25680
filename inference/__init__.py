"""pgm.inference: the generic engine and its algorithms (SMC, particle BP, VB, PHD)."""

from . import (
    association,
    batched,
    particles,
    pbp,
    phd,
    plates,
    resampling,
    rules,
    schedule,
    vb,
)
from .context import RuleContext
from .engine import (
    DEFAULT_RULES,
    Engine,
    RuleTable,
    Schedule,
    StepRecord,
    derive_schedule,
    message_order,
)
from .kalman import KalmanResult, kalman_filter, linear_gaussian_matrices
from .rules import RuleTable as _RuleTable

#: the rule families, in the order their tables are gathered (no two register one key)
FAMILIES = (particles, pbp, batched, phd, vb, association)


def default_rules() -> _RuleTable:
    """A new table of every family's rules: particle SMC (:mod:`~pgm.inference.particles`),
    particle BP (:mod:`~pgm.inference.pbp`), the batched plate rules
    (:mod:`~pgm.inference.batched`), the PHD corrector (:mod:`~pgm.inference.phd`),
    mean-field VB and the exact Gaussian rules (:mod:`~pgm.inference.vb`), and the exact
    Kalman replicas with data association (:mod:`~pgm.inference.association`)."""
    table = _RuleTable()
    for family in FAMILIES:
        table.update(family.RULES)
    return table


#: the table an :class:`Engine` uses unless given another: :func:`default_rules`, which a
#: user may extend (``DEFAULT_RULES.register(...)``) or copy first
DEFAULT_RULES.update(default_rules())

__all__ = ["Engine", "RuleTable", "DEFAULT_RULES", "Schedule", "StepRecord", "derive_schedule",
           "kalman_filter", "KalmanResult", "linear_gaussian_matrices", "resampling", "pbp",
           "message_order", "phd", "vb", "plates", "batched", "rules", "schedule", "particles",
           "association", "default_rules", "FAMILIES", "RuleContext"]
