"""pgm: visual trackers declared as explicit probabilistic factor graphs.

Declare variables and factors, put them in a :class:`FactorGraph`, and run it with
:class:`pgm.inference.Engine`; ready-made trackers are in :mod:`pgm.models`.
"""

from .beliefs import Intensity, Particles
from .errors import DegenerateWeightsError, InputError
from .factors import (
    AR2Transition,
    ConjugateFactor,
    CouplingFactor,
    Factor,
    GaussianPrior,
    LikelihoodFactor,
    LinearGaussianLikelihood,
    LinearGaussianTransition,
    PriorFactor,
    TransitionFactor,
)
from .frame import FrameContext
from .graph import FactorGraph
from .variable import ROLES, Variable

__version__ = "0.1.0"

__all__ = [
    "Variable", "ROLES", "Factor", "PriorFactor", "TransitionFactor", "LikelihoodFactor",
    "CouplingFactor", "ConjugateFactor", "GaussianPrior", "LinearGaussianTransition",
    "AR2Transition", "LinearGaussianLikelihood", "FactorGraph", "FrameContext", "Particles",
    "Intensity", "InputError", "DegenerateWeightsError", "__version__",
]
