"""pgm.models: model configs — functions that build a :class:`~pgm.FactorGraph`.

Each model module has a frozen ``Params`` dataclass and ``build_graph(params)``.
:data:`MODELS` maps the CLI's model names to them.
"""

from . import colour_pf, gpdm, linear_gaussian, multi_pf, part_graph, phd, single_object, vb_phd

__all__ = ["colour_pf", "gpdm", "linear_gaussian", "multi_pf", "part_graph", "phd", "single_object",
           "vb_phd", "MODELS", "get_model", "DEFAULT_SINGLE_OBJECT"]

#: CLI model name → module with ``Params`` and ``build_graph``
MODELS = {"colour-pf": colour_pf, "part-graph": part_graph, "phd": phd, "vb-phd": vb_phd,
          "single-object": single_object, "multi-pf": multi_pf, "gpdm": gpdm}
#: what ``pgm track`` runs on a single object when no ``--model`` is given
DEFAULT_SINGLE_OBJECT = "single-object"


def get_model(name: str):
    """The model module called ``name`` (e.g. ``"colour-pf"``)."""
    try:
        return MODELS[name]
    except KeyError:
        raise ValueError(f"unknown model {name!r} (choose from {', '.join(sorted(MODELS))})") \
            from None
