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
from pgm.core.version import __version__
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

#: the modules that define the toolkit's factor types and readouts, imported when a saved
#: graph names one that is not registered yet (some pull torch or a model file, so they are
#: not imported with ``pgm``)
TOOLKIT_MODULES = ("pgm.factors", "pgm.factors.plates", "pgm.factors.multitarget",
                   "pgm.factors.association", "pgm.factors.detection_association",
                   "pgm.factors.scores",
                   "pgm.observation.appearance.likelihoods",
                   "pgm.observation.appearance.correlation", "pgm.dynamics.factors",
                   "pgm.observation.appearance.dbn", "pgm.inference.plates")


def _find_toolkit_names(found, module=None) -> None:
    """Import, until ``found()``: the module a saved declaration names when it is the
    toolkit's (``pgm.*``) or an installed plug-in's (a ``pgm.models`` entry point), then the
    toolkit's factor modules and plate engine, then the models' modules (the toolkit's, then
    the plug-ins'). Installed code only, never a file's; a broken plug-in is skipped."""
    import importlib
    from importlib.metadata import entry_points

    plugins = [ep.value.partition(":")[0] for ep in entry_points(group="pgm.models")]
    named = [module] if module and (module.startswith("pgm.") or module in plugins) else []
    for name in named + list(TOOLKIT_MODULES):
        if found():
            return
        try:
            importlib.import_module(name)
        except ImportError:
            if name in named:  # a module the toolkit no longer has: look further
                continue
            raise
    models = list(importlib.import_module("pgm.models").BUILTIN.values())
    for target in [t.partition(":")[0] for t in models] + plugins:
        if found():
            return
        try:
            importlib.import_module(target)
        except Exception:  # noqa: BLE001 - a broken plug-in registers nothing
            continue


from pgm.core.factor import register_finder as _register_finder  # noqa: E402

_register_finder(_find_toolkit_names)

from pgm.core.graph import register_drawing as _register_drawing  # noqa: E402
from pgm.plotting.graph_drawing import draw as _draw  # noqa: E402
from pgm.plotting.graph_drawing import to_dot as _to_dot  # noqa: E402

_register_drawing(_draw, _to_dot)

#: the toolkit's subpackages, imported on first use as attributes of ``pgm``
#: (``import pgm; pgm.inference.Engine``) so that ``import pgm`` and ``pgm --help`` stay fast
SUBPACKAGES = ("app", "core", "dynamics", "evaluation", "factors", "inference", "io", "models",
               "observation", "plotting", "synthetic")


def __getattr__(name: str):
    """``pgm.inference``, ``pgm.models``, ...: the subpackage, imported on first use."""
    if name in SUBPACKAGES:
        import importlib

        return importlib.import_module(f"pgm.{name}")
    raise AttributeError(f"module 'pgm' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(SUBPACKAGES))


__all__ = [
    "Variable", "ROLES", "Factor", "PriorFactor", "TransitionFactor", "LikelihoodFactor",
    "CouplingFactor", "ConjugateFactor", "GaussianPrior", "LinearGaussianTransition",
    "AR2Transition", "LinearGaussianLikelihood", "FactorGraph", "FrameContext", "Particles",
    "Intensity", "InputError", "DegenerateWeightsError", "__version__", "Plate", "Lifecycle",
    "InteractionFactor", "MutualExclusion", "DetectionLikelihood",
]
