"""Appearance cues by name: the ``appearance`` strings of the model configs.

An ``appearance`` string such as ``"fragments+gradient"`` or ``"cf(lam=20,padding=2)"``
names likelihood factors of :mod:`pgm.observation.appearance` joined by ``+``, each with
optional numeric keyword options; :func:`appearance_cues` parses it (a ``ValueError``
naming the cue on a bad one) and :func:`cue_factor` builds a cue's factor on a box
variable.

>>> appearance_cues("cf(lam=20,padding=2)+template")
[('cf', {'lam': 20, 'padding': 2}), ('template', {})]
"""

from __future__ import annotations

import re

from pgm.observation.appearance.correlation import CorrelationFilterLikelihood
from pgm.observation.appearance.likelihoods import (
    ColourContrastLikelihood,
    ColourHistogramLikelihood,
    FragmentsLikelihood,
    GMMKLLikelihood,
    GradientLikelihood,
    RotationInvariantLikelihood,
    TemplateLikelihood,
)
from pgm.observation.appearance.scale_filter import ScaleFilterLikelihood

__all__ = ["CUES", "appearance_cues", "cue_factor"]

#: the cues an ``appearance`` string may combine with "+" (each a likelihood factor)
CUES = ("colour", "fragments", "gradient", "gmm", "rings", "contrast", "template", "cf", "scale")


def appearance_cues(appearance: str) -> list[tuple[str, dict[str, float]]]:
    """The cues of an ``appearance`` string such as ``"fragments+gradient"``, each with
    its options: ``"cf(lam=20,padding=2)+template"`` sets the correlation filter's
    ``lam`` and ``padding`` (any keyword of the cue's factor; numbers only)."""
    out: list[tuple[str, dict[str, float]]] = []
    for part in str(appearance).split("+"):
        part = part.strip()
        name, opts = part, {}
        if "(" in part:
            if not part.endswith(")"):
                raise ValueError(f"appearance cue {part!r}: options go in one pair of "
                                 f"parentheses, e.g. cf(lam=20,padding=2)")
            name, body = part[:-1].split("(", 1)
            name = name.strip()
            for item in filter(None, (b.strip() for b in body.split(","))):
                key, sep, value = item.partition("=")
                try:
                    num = float(value)
                except ValueError:
                    num = None
                if not sep or not key.strip().isidentifier() or num is None:
                    raise ValueError(f"appearance cue {part!r}: options must be key=number, "
                                     f"got {item!r}")
                opts[key.strip()] = int(num) if value.strip().lstrip("-").isdigit() else num
        out.append((name, opts))
    names = [n for n, _ in out]
    bad = [n for n in names if n not in CUES]
    if bad or len(set(names)) != len(names):
        raise ValueError(f"appearance must be distinct cues from {CUES} joined by '+', got "
                         f"{appearance!r}")
    return out


def cue_factor(cue: str, variable: str, params, name: str | None = None,
               options: dict[str, float] | None = None):
    """The likelihood factor of one appearance cue on a box variable. ``params`` gives
    the model's shared settings (attributes ``lam``, ``layout``, ``kernel``: e.g. a
    :class:`pgm.models.part_graph.Params`); ``options`` extra keywords for the factor,
    from the appearance string."""
    kw = dict(options or {})
    try:
        return _cue_factor(cue, variable, params, name, kw)
    except TypeError as e:
        # name the option the factor refused (a model may add options of its own to kw)
        unknown = re.search(r"unexpected keyword argument '(\w+)'", str(e))
        what = f"unknown option {unknown.group(1)!r}" if unknown else f"bad option ({e})"
        raise ValueError(f"appearance cue {cue!r}: {what}") from None


def _cue_factor(cue, variable, params, name, kw):
    if cue == "colour":
        return ColourHistogramLikelihood(variable, **{"lam": params.lam, "layout": params.layout,
                                                      "kernel": params.kernel, **kw}, name=name)
    if cue == "fragments":
        return FragmentsLikelihood(variable, **{"lam": params.lam, "layout": params.layout,
                                                **kw}, name=name)
    if cue == "gradient":
        return GradientLikelihood(variable, **{"lam": params.lam / 2, **kw}, name=name)
    if cue == "gmm":
        return GMMKLLikelihood(variable, **kw, name=name)
    if cue == "contrast":
        return ColourContrastLikelihood(variable, **{"layout": params.layout, **kw}, name=name)
    if cue == "template":
        return TemplateLikelihood(variable, **{"lam": params.lam, **kw}, name=name)
    if cue == "cf":
        return CorrelationFilterLikelihood(variable, **kw, name=name)
    if cue == "scale":
        return ScaleFilterLikelihood(variable, **kw, name=name)
    return RotationInvariantLikelihood(variable, **kw, name=name)
