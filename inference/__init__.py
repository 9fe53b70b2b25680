"""pgm.inference: the generic engine and its algorithms (SMC, particle BP, VB, PHD)."""

from . import batched, particles, pbp, phd, plates, resampling, rules, schedule, vb
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

__all__ = ["Engine", "RuleTable", "DEFAULT_RULES", "Schedule", "StepRecord", "derive_schedule",
           "kalman_filter", "KalmanResult", "linear_gaussian_matrices", "resampling", "pbp",
           "message_order", "phd", "vb", "plates", "batched", "rules", "schedule", "particles"]
