"""The per-frame schedule an engine derives from the factor kinds of its graph.

A frame's stages, in order: **predict** (the first frame: **prior**), **assign** (the
data-association factors of a plate: the frame's detections given to its replicas, so that
each replica's likelihood reads the one assigned to it), **weight**
(likelihoods), **interaction** (factors between the replicas of a plate), **inframe**
(coupling messages of particle BP and the VB fixed point of conjugate factors), **fuse**,
**estimate**, **resample** and, for a graph with a plate, **associate** (the track layer:
the replicas' boxes against the frame's detections; births and deaths). Every factor of
the graph is run by one stage: a factor of a kind no stage runs is an error at
construction, never dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

from pgm.core.graph import FactorGraph

from .settings import FUSIONS

__all__ = ["STAGES", "Schedule", "message_order", "derive_schedule"]

STAGES = ("prior", "predict", "assign", "weight", "interaction", "inframe", "fuse", "estimate",
          "resample", "associate")

@dataclass
class Schedule:
    """The per-frame schedule: ``phases`` is a list of ``(stage, items)``.

    ``items`` are factor names for factor stages, ``(coupling, src, dst)`` triples for
    directed messages in the ``inframe`` stage, and variable names for ``fuse``,
    ``estimate`` and ``resample``.
    """

    first_frame: list[tuple[str, list]]
    phases: list[tuple[str, list]]

    def __repr__(self) -> str:
        def item(i):
            return f"{i[1]}→{i[2]}" if isinstance(i, tuple) else str(i)

        def fmt(ph):
            return " → ".join(f"{s}[{', '.join(item(i) for i in items)}]"
                              for s, items in ph if items)

        return f"Schedule(\n  first: {fmt(self.first_frame)}\n  step:  {fmt(self.phases)}\n)"


def message_order(graph: FactorGraph, fusion: str = "mixture",
                  iterations: int = 1) -> list[tuple[str, str, str]]:
    """Directed coupling messages ``(factor, src, dst)`` for one frame.

    ``"mixture"``: every directed edge once (all messages leave this frame's predicted
    particles). ``"product"``: on a forest, a leaves-to-root then root-to-leaves sweep
    (exact for trees); with loops, ``iterations`` flooding rounds.
    """
    import networkx as nx

    couplings = graph.factors_by_kind("coupling")
    if not couplings:
        return []
    flood = [(f.name, f.variables[1], f.variables[0]) for f in couplings] + \
            [(f.name, f.variables[0], f.variables[1]) for f in couplings]
    if fusion == "mixture":
        return flood
    g = nx.MultiGraph()
    for f in couplings:
        g.add_edge(*f.variables, key=f.name)
    if not nx.is_forest(nx.Graph(g)) or g.number_of_edges() != nx.Graph(g).number_of_edges():
        return flood * max(1, iterations)
    by_pair = {frozenset(f.variables): f.name for f in couplings}
    order: list[tuple[str, str, str]] = []
    for comp in nx.connected_components(g):
        root = min(comp, key=list(graph.variables).index)
        tree_edges = list(nx.dfs_edges(nx.Graph(g).subgraph(comp), root))  # parent -> child
        up = [(by_pair[frozenset((p, c))], c, p) for p, c in reversed(tree_edges)]
        down = [(by_pair[frozenset((p, c))], p, c) for p, c in tree_edges]
        order += up + down
    return order


def derive_schedule(graph: FactorGraph, inframe_iterations: int = 1,
                    fusion: str = "mixture") -> Schedule:
    """Derive the per-frame schedule from the factor kinds of ``graph``."""
    if inframe_iterations < 0:
        raise ValueError(f"inframe_iterations must be >= 0, got {inframe_iterations}")
    if fusion not in FUSIONS:
        raise ValueError(f"unknown fusion {fusion!r} (choose from {FUSIONS})")
    names = lambda kind: [f.name for f in graph.factors_by_kind(kind)]  # noqa: E731
    # likelihoods parameterised by a noise variable are updated inside the VB fixed point
    under_vb: set[str] = set()
    for c in graph.factors_by_kind("conjugate"):
        lik = getattr(c, "likelihood", None)
        under_vb |= ({lik} if lik else {f.name for f in graph.factors_of(c.variables[1],
                                                                         "likelihood")})
    messages = message_order(graph, fusion, inframe_iterations)
    conjugates = names("conjugate") * (inframe_iterations if names("conjugate") else 0)
    receivers = [v for v in graph.variables if any(dst == v for _, _, dst in messages)]
    particle_vars = [v.name for v in graph.variables.values() if v.role != "noise"]
    weighted = [n for n in names("likelihood") if n not in under_vb]
    interactions = names("interaction")
    assignments = names("association")
    for kind, fs in (("interaction", interactions), ("association", assignments)):
        if fs and not graph.plates:
            raise ValueError(f"factor {fs[0]!r} of kind {kind!r} links the replicas of a plate; "
                             f"graph {graph.name!r} declares no plate")
    if len(assignments) > 1:
        raise ValueError(f"graph {graph.name!r}: one association factor per plate, got "
                         f"{assignments}")
    tail = [("weight", weighted), ("interaction", interactions),
            ("inframe", messages + conjugates), ("fuse", receivers),
            ("estimate", list(graph.variables)), ("resample", particle_vars)]
    if graph.plates:
        tail.append(("associate", [p.name for p in graph.plates]))
    schedule = Schedule(first_frame=[("prior", names("prior"))] + tail,
                        phases=[("predict", names("transition")),
                                ("assign", assignments)] + tail)
    scheduled = {i[0] if isinstance(i, tuple) else i
                 for phases in (schedule.first_frame, schedule.phases) for _, items in phases
                 for i in items}
    for f in graph.factors_by_kind("proposal"):  # the predict stage draws from it
        if not graph.factors_of(f.variables[0], "transition"):
            raise ValueError(f"proposal {f.name!r}: variable {f.variables[0]!r} has no "
                             f"transition to propose in place of")
        if len(graph.factors_of(f.variables[0], "proposal")) > 1:
            raise ValueError(f"variable {f.variables[0]!r} has more than one proposal")
        scheduled.add(f.name)
    for f in graph.factors.values():
        off = f.kind == "conjugate" and inframe_iterations == 0  # VB switched off
        if f.name not in scheduled and f.name not in under_vb and not off:
            raise ValueError(f"factor {f.name!r} of kind {f.kind!r}: no stage of the engine's "
                             f"schedule runs it")
    return schedule
