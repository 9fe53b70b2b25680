"""pgm.models: model configs — functions that build a :class:`~pgm.FactorGraph`.

Each model module has a frozen ``Params`` dataclass, ``build_graph(params)`` and a
``CONFIG`` (:class:`pgm.models.config.ModelConfig`) that tells the application its
name, its kind and its command-line options. Models are found through the ``pgm.models``
entry points: the toolkit's own (:data:`BUILTIN`) and those of any installed package
(``[project.entry-points."pgm.models"] my-tracker = "my_package.my_tracker:CONFIG"``),
so a model of your own appears in ``pgm track --model``, ``pgm graph`` and ``pgm bench``
without touching the toolkit (``docs/tutorials/08_model_plugin.py``).

Listing the names imports no model (:func:`model_names`); :func:`get_config` imports one.
"""

from __future__ import annotations

import importlib
from typing import Any

from . import config
from .config import ModelConfig

__all__ = ["BUILTIN", "model_names", "get_config", "get_model", "registry", "option_owners",
           "DEFAULT_SINGLE_OBJECT", "DEFAULT_MULTI_TARGET", "ENTRY_POINT_GROUP", "config",
           "ModelConfig", "botsort", "bytetrack", "cbiou", "colour_pf", "gpdm",
           "linear_gaussian", "multi_pf", "ocsort", "ocsort_colour", "part_graph", "phd",
           "single_object", "sort", "vb_phd", "vb_sort"]

#: the entry-point group where packages declare models
ENTRY_POINT_GROUP = "pgm.models"
#: the toolkit's own models: name → ``module:attribute`` of their :class:`ModelConfig`
#: (also declared as entry points in the toolkit's ``pyproject.toml``)
BUILTIN = {
    "botsort": "pgm.models.botsort:CONFIG",
    "bytetrack": "pgm.models.bytetrack:CONFIG",
    "cbiou": "pgm.models.cbiou:CONFIG",
    "colour-pf": "pgm.models.colour_pf:CONFIG",
    "gpdm": "pgm.models.gpdm:CONFIG",
    "linear-gaussian": "pgm.models.linear_gaussian:CONFIG",
    "multi-pf": "pgm.models.multi_pf:CONFIG",
    "ocsort": "pgm.models.ocsort:CONFIG",
    "ocsort-colour": "pgm.models.ocsort_colour:CONFIG",
    "part-graph": "pgm.models.part_graph:CONFIG",
    "phd": "pgm.models.phd:CONFIG",
    "single-object": "pgm.models.single_object:CONFIG",
    "sort": "pgm.models.sort:CONFIG",
    "vb-sort": "pgm.models.vb_sort:CONFIG",
    "vb-phd": "pgm.models.vb_phd:CONFIG",
}
#: what ``pgm track`` runs on a single object when no ``--model`` is given
DEFAULT_SINGLE_OBJECT = "single-object"
#: what ``pgm track`` runs on a video with detections when no ``--model`` is given: chosen
#: leave one sequence out over the shared MOT sequences and their perturbations
#: (``benchmarks/robustness.py``; docs/results.md)
DEFAULT_MULTI_TARGET = "ocsort-colour"

_SUBMODULES = ("botsort", "bytetrack", "cbiou", "colour_pf", "gpdm", "linear_gaussian",
               "multi_pf", "ocsort", "ocsort_colour", "part_graph", "phd", "single_object",
               "sort", "vb_phd", "vb_sort")


def __getattr__(name: str) -> Any:
    """The model modules, imported on first use (listing names stays cheap)."""
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _entry_points() -> dict[str, Any]:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def model_names() -> list[str]:
    """Every model name: the toolkit's and the installed packages' (imports none)."""
    return sorted(set(BUILTIN) | set(_entry_points()))


def _load(name: str, target: str | Any) -> ModelConfig:
    try:
        if isinstance(target, str):
            module, _, attr = target.partition(":")
            obj = getattr(importlib.import_module(module), attr)
        else:
            obj = target.load()
    except Exception as exc:  # a broken plug-in: say which, do not crash the listing
        where = target if isinstance(target, str) else target.value
        raise ValueError(f"model {name!r} ({where}) cannot be loaded: "
                         f"{type(exc).__name__}: {exc}") from None
    if not isinstance(obj, ModelConfig):
        obj = getattr(obj, "CONFIG", obj)  # an entry point may name the module
    if not isinstance(obj, ModelConfig):
        raise ValueError(f"model {name!r}: its entry point names {type(obj).__name__}, not a "
                         f"pgm.models.config.ModelConfig")
    if obj.name != name:
        raise ValueError(f"model {name!r}: its entry point names the config of {obj.name!r}")
    return obj


def get_config(name: str) -> ModelConfig:
    """The :class:`ModelConfig` called ``name`` (a ``ValueError`` listing the names if
    there is none)."""
    eps = _entry_points()
    if name in BUILTIN:  # the toolkit's own, even where the distribution is not installed
        return _load(name, BUILTIN[name])
    if name in eps:
        return _load(name, eps[name])
    raise ValueError(f"unknown model {name!r} (choose from {', '.join(model_names())})")


def get_model(name: str):
    """The module of the model called ``name`` (its ``Params`` and ``build_graph``)."""
    return get_config(name).module


def registry() -> dict[str, ModelConfig]:
    """Every model's config, by name (imports every model)."""
    return {name: get_config(name) for name in model_names()}


def option_owners() -> dict[str, list[tuple[str, config.Option]]]:
    """Every model option flag → the ``(model name, option)`` pairs that declare it
    (imports every model; a plug-in that cannot be loaded declares nothing)."""
    owners: dict[str, list[tuple[str, config.Option]]] = {}
    for name in model_names():
        try:
            options = get_config(name).options
        except ValueError:
            continue
        for opt in options:
            owners.setdefault(opt.flag, []).append((name, opt))
    return owners

