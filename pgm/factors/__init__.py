"""Factors: the kind base classes, generic Gaussian factors, the motion library in physical
units (:mod:`pgm.factors.motion`), couplings between parts and the multi-target factors
(PHD measurement model, noise priors, VB conjugate factor).

The root :class:`~pgm.core.factor.Factor` and the by-name registry live in
:mod:`pgm.core.factor`; everything here is a subclass of it.
"""

from pgm.core.factor import KINDS, Factor, factor_from_dict, registered_factor_types
from pgm.factors.gaussian import (
    AR2Transition,
    AveragedVelocityTransition,
    GaussianPrior,
    LinearGaussianLikelihood,
    LinearGaussianProposal,
    LinearGaussianTransition,
)
from pgm.factors.kinds import (
    ConjugateFactor,
    CouplingFactor,
    LikelihoodFactor,
    PriorFactor,
    ProposalFactor,
    TransitionFactor,
)
from pgm.factors.motion import MotionTransition

__all__ = ["Factor", "PriorFactor", "ProposalFactor", "TransitionFactor", "LikelihoodFactor",
           "CouplingFactor", "LinearGaussianProposal",
           "ConjugateFactor", "GaussianPrior", "LinearGaussianTransition", "AR2Transition",
           "AveragedVelocityTransition",
           "LinearGaussianLikelihood", "factor_from_dict", "registered_factor_types", "KINDS",
           "MotionTransition"]
