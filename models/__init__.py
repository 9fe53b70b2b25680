"""pgm.models: model configs — functions that build a :class:`~pgm.FactorGraph`.

Each model module has a frozen ``Params`` dataclass and ``build_graph(params)``.
:data:`MODELS` maps the CLI's model names to them.
"""

from . import colour_pf, linear_gaussian, part_graph, phd, vb_phd

__all__ = ["colour_pf", "linear_gaussian", "part_graph", "phd", "vb_phd", "MODELS", "get_model"]

#: CLI model name → module with ``Params`` and ``build_graph``
MODELS = {"colour-pf": colour_pf, "part-graph": part_graph, "phd": phd, "vb-phd": vb_phd}


def get_model(name: str):
    """The model module called ``name`` (e.g. ``"colour-pf"``)."""
    try:
        return MODELS[name]
    except KeyError:
        raise ValueError(f"unknown model {name!r} (choose from {', '.join(sorted(MODELS))})") \
            from None
