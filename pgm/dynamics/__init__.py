"""Learned motion models (dynamics) for the per-target chains of the trackers.

:mod:`pgm.dynamics.gpdm` is the Gaussian-process dynamical model of Wang, Yin & Man (2008),
with the fixes it needs to have a finite optimum; its :func:`~pgm.dynamics.gpdm.predict` samples future
boxes and falls back to constant velocity when a track is too young.

:mod:`pgm.dynamics.factors` makes it a factor of the generic engine
(:class:`~pgm.dynamics.factors.GPDMTransition`, :class:`~pgm.dynamics.factors.GPDMPrior`).
This subpackage imports numpy, scipy, torch, :mod:`pgm.core` and the factor kinds of
:mod:`pgm.factors` only (a test enforces it), so model configs, the CLI and benchmarks
can all call it.
"""

try:  # torch is the optional `learn` extra: learned dynamics need it, the toolkit does not
    import torch  # noqa: F401
except ImportError:  # pragma: no cover - exercised by a test that hides torch
    from pgm.core.errors import InputError

    raise InputError("learned dynamics (GPDM) need torch: pip install 'pgm-tracking[learn]'") \
        from None

from .gpdm import (  # noqa: E402
    GPDM,
    GPDMSettings,
    Trajectory,
    apply_differences,
    box_differences,
    dynamics_kernel,
    fit_gpdm,
    gt_trajectories,
    learn_gpdm,
    load_gpdm,
    observation_kernel,
    predict,
    predict_constant_velocity,
)

__all__ = ["GPDM", "GPDMSettings", "Trajectory", "apply_differences", "box_differences",
           "dynamics_kernel", "fit_gpdm", "gt_trajectories", "learn_gpdm", "load_gpdm",
           "observation_kernel", "predict", "predict_constant_velocity"]
