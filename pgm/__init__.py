"""pgm: visual trackers declared as explicit probabilistic factor graphs.

Declare variables and factors, put them in a :class:`FactorGraph`, and run it with
:class:`pgm.inference.Engine`; ready-made trackers are in :mod:`pgm.models`.
"""

from pgm.core.beliefs import Intensity, Particles
from pgm.core.errors import DegenerateWeightsError, InputError
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.plate import Lifecycle, Plate
from pgm.core.variable import ROLES, Variable
from pgm.factors import (
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
from pgm.factors.plates import DetectionLikelihood, InteractionFactor, MutualExclusion

__version__ = "0.1.0"

__all__ = [
    "Variable", "ROLES", "Factor", "PriorFactor", "TransitionFactor", "LikelihoodFactor",
    "CouplingFactor", "ConjugateFactor", "GaussianPrior", "LinearGaussianTransition",
    "AR2Transition", "LinearGaussianLikelihood", "FactorGraph", "FrameContext", "Particles",
    "Intensity", "InputError", "DegenerateWeightsError", "__version__", "Plate", "Lifecycle",
    "InteractionFactor", "MutualExclusion", "DetectionLikelihood",
]
