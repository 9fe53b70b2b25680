"""Drawing factor graphs in standard notation.

Variables are circles coloured by role; factors are small squares coloured by kind.
Unary factors sit around their variable (prior on the left, transition above, drawn
with a loop to ``t-1``, likelihoods below next to a shaded circle for the observed
frame ``z_t``); a factor linking several variables sits between them. A plate (one
sub-graph per target) is a box around its variables and their factors labelled with its
size (``K``), as in the textbooks; a factor between the replicas (kind
``"interaction"``) sits on the box's edge with a dashed link to the other replicas.
Output is PNG/SVG/PDF through matplotlib (no Graphviz binary needed) or DOT text.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from pgm.core.graph import FactorGraph

__all__ = ["to_dot", "draw", "layout", "ROLE_COLOURS", "KIND_COLOURS"]

ROLE_COLOURS = {"part": "#8ecae6", "state": "#b7e4c7", "latent": "#ffd6a5",
                "noise": "#e0aaff", "set": "#ffadad"}
KIND_COLOURS = {"prior": "#6c757d", "transition": "#1d3557", "likelihood": "#e63946",
                "coupling": "#f4a261", "conjugate": "#7b2cbf", "interaction": "#2a9d8f",
                "proposal": "#457b9d", "association": "#e9c46a"}
_UNARY_ANGLE = {"prior": 5 * np.pi / 6, "transition": np.pi / 2, "likelihood": -np.pi / 2,
                "conjugate": np.pi / 6, "coupling": 0.0, "interaction": 0.0,
                "proposal": np.pi / 6, "association": -5 * np.pi / 6}


def _dot_id(name: str) -> str:
    return '"' + name.replace('"', '\\"') + '"'


def to_dot(graph: FactorGraph) -> str:
    """DOT text: ``graph`` with circle variables and box factors, coloured by role/kind."""
    lines = [f"graph {_dot_id(graph.name)} {{", "  layout=neato; overlap=false; splines=true;"]
    for v in graph.variables.values():
        lines.append(f"  {_dot_id(v.name)} [shape=circle, style=filled, "
                     f"fillcolor=\"{ROLE_COLOURS[v.role]}\", label=\"{v.name}\\n({v.role})\"];")
    for p in graph.plates:
        members = set(p.variables) | {f.name for f in graph.factors.values()
                                      if f.kind != "interaction"
                                      and all(v in p.variables for v in f.variables)}
        lines.append(f"  subgraph {_dot_id('cluster_' + p.name)} {{")
        lines.append(f"    label=\"{p.name} ({p.size_label})\"; labelloc=b; labeljust=r;")
        lines += [f"    {_dot_id(n)};" for n in sorted(members)]
        lines.append("  }")
    for f in graph.factors.values():
        lines.append(f"  {_dot_id(f.name)} [shape=square, style=filled, width=0.25, "
                     f"fixedsize=true, label=\"\", fillcolor=\"{KIND_COLOURS[f.kind]}\", "
                     f"xlabel=\"{type(f).__name__}\"];")
        for var in f.variables:
            lines.append(f"  {_dot_id(f.name)} -- {_dot_id(var)};")
    for f in graph.factors_by_kind("likelihood"):
        z = f"z:{f.name}"
        lines.append(f"  {_dot_id(z)} [shape=circle, style=filled, fillcolor=\"#adb5bd\", "
                     f"label=\"z\"];")
        lines.append(f"  {_dot_id(f.name)} -- {_dot_id(z)};")
    lines.append("}")
    return "\n".join(lines) + "\n"


def layout(graph: FactorGraph) -> dict[str, np.ndarray]:
    """Positions of variables, factors and observed nodes (``"z:<factor>"``)."""
    import networkx as nx

    names = list(graph.variables)
    var_graph = nx.Graph()
    var_graph.add_nodes_from(names)
    for f in graph.factors.values():
        for a in f.variables:
            for b in f.variables:
                if a < b:
                    var_graph.add_edge(a, b)
    if len(names) == 1:
        pos = {names[0]: np.zeros(2)}
    elif nx.is_forest(var_graph) and max(dict(var_graph.degree).values()) <= 2:
        # chains: a horizontal row, in path order
        pos = {}
        x = 0.0
        for comp in nx.connected_components(var_graph):
            sub = var_graph.subgraph(comp)
            ends = [n for n in sub if sub.degree[n] <= 1]
            order = list(nx.dfs_preorder_nodes(sub, ends[0]))
            for n in order:
                pos[n] = np.array([x, 0.0])
                x += 3.5
    else:
        raw = nx.circular_layout(var_graph, scale=3.0)
        pos = {n: np.asarray(p) for n, p in raw.items()}
    out: dict[str, np.ndarray] = dict(pos)
    counts: dict[tuple[str, str], int] = {}
    n_lik = {v: len([f for f in graph.factors_of(v, "likelihood") if len(f.variables) == 1])
             for v in names}
    for f in graph.factors.values():
        if len(f.variables) == 1:
            v = f.variables[0]
            key = (v, f.kind)
            k = counts.get(key, 0)
            counts[key] = k + 1
            if f.kind == "likelihood" and n_lik[v] > 1:
                # several cues on one variable: a row below it, each with its own z
                step = min(1.9, 3.3 / n_lik[v])
                dx = (k - (n_lik[v] - 1) / 2) * step
                out[f.name] = pos[v] + np.array([dx, -1.2])
                out[f"z:{f.name}"] = pos[v] + np.array([dx, -2.2])
                continue
            ang = _UNARY_ANGLE[f.kind] + 0.45 * k * (-1) ** k
            out[f.name] = pos[v] + 1.1 * np.array([np.cos(ang), np.sin(ang)])
            if f.kind == "likelihood":
                out[f"z:{f.name}"] = pos[v] + 2.0 * np.array([np.cos(ang), np.sin(ang)])
        else:
            out[f.name] = np.mean([pos[v] for v in f.variables], axis=0)
    for f in graph.factors_by_kind("conjugate"):  # between the noise node and the
        # likelihood(s) it parameterises (drawn linked to them)
        liks = parameterised(graph, f)
        if liks:
            out[f.name] = 0.5 * (pos[f.variables[0]] + np.mean([out[n] for n in liks], axis=0))
    for (x0, _y0, _x1, y1), p in zip(plate_boxes(graph, out), graph.plates, strict=True):
        for f in graph.factors.values():  # on the plate's edge: they couple the replicas
            if f.kind == "interaction" and f.variables[0] in p.variables:
                out[f.name] = np.array([out[f.variables[0]][0] + 1.2, y1])
            elif f.kind == "association" and f.variables[0] in p.variables:
                out[f.name] = np.array([x0, out[f.variables[0]][1] - 0.9])
    return out


#: factor kinds that couple all the replicas of a plate: drawn on its edge, not inside
ACROSS_PLATE = ("interaction", "association")


def parameterised(graph: FactorGraph, factor) -> list[str]:
    """The likelihood factors a conjugate factor parameterises (its ``likelihood``, or
    every likelihood of its target)."""
    lik = getattr(factor, "likelihood", None)
    if lik:
        return [lik] if lik in graph.factors else []
    return [f.name for f in graph.factors_of(factor.variables[1], "likelihood")]


def plate_outlines(graph: FactorGraph, pos: dict[str, np.ndarray]) -> list[tuple]:
    """``((x0, y0, x1, y1), plate)`` for each plate of ``graph`` (:func:`plate_boxes`)."""
    return list(zip(plate_boxes(graph, pos), graph.plates, strict=True))


def plate_boxes(graph: FactorGraph, pos: dict[str, np.ndarray]
                ) -> list[tuple[float, float, float, float]]:
    """``(x0, y0, x1, y1)`` of each plate: around its variables, their factors and each
    replica's observations (not the factors between replicas, which sit on its edge)."""
    out = []
    for p in graph.plates:
        inside = [f for f in graph.factors.values() if f.kind not in ACROSS_PLATE
                  and all(v in p.variables for v in f.variables)]
        names = list(p.variables) + [f.name for f in inside] + [
            f"z:{f.name}" for f in inside if f.kind == "likelihood"]
        pts = np.array([pos[n] for n in names if n in pos])
        lo, hi = pts.min(axis=0) - 0.75, pts.max(axis=0) + 0.75
        out.append((float(lo[0]), float(lo[1]), float(hi[0] + 0.4), float(hi[1])))
    return out


def draw(graph: FactorGraph, path: str | Path | None = None, ax=None,
         title: str | None = None, **_: Any):
    """Draw ``graph``; save to ``path`` (.png, .svg, .pdf or .dot) if given; return the axes."""
    if path is not None and Path(path).suffix.lower() == ".dot":
        Path(path).write_text(to_dot(graph))
        return None
    if path is not None and Path(path).suffix.lower() not in (".png", ".svg", ".pdf"):
        raise ValueError(f"cannot draw to {path}: use .png, .svg, .pdf or .dot")
    import matplotlib

    if ax is None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, FancyArrowPatch, Rectangle

    pos = layout(graph)
    own_fig = ax is None
    if own_fig:
        xs = np.array([p[0] for p in pos.values()])
        ys = np.array([p[1] for p in pos.values()])
        w = max(4.0, (xs.max() - xs.min()) * 1.2 + 3)
        h = max(3.5, (ys.max() - ys.min()) * 1.2 + 2.5)
        fig, ax = plt.subplots(figsize=(w, h))
    r_var, s_fac = 0.45, 0.28
    for (x0, y0, x1, y1), p in zip(plate_boxes(graph, pos), graph.plates, strict=True):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fc="none", ec="#333", lw=1.4,
                               zorder=0.5))
        ax.text(x1 + 0.1, y0 + 0.05, p.size_label, ha="left", va="bottom", fontsize=12,
                style="italic", zorder=4)  # outside the corner, clear of the labels in it
        ax.text(x0 + 0.12, y1 - 0.12, p.name, ha="left", va="top", fontsize=8, color="#333",
                zorder=4)
    for f in graph.factors_by_kind("interaction"):
        q = pos[f.name]
        ax.plot([q[0], q[0] + 0.6], [q[1], q[1] + 0.6], color="#2a9d8f", lw=1.2, ls="--",
                zorder=1)
        ax.text(q[0] + 0.65, q[1] + 0.65, "j≠k", ha="left", va="bottom", fontsize=7,
                color="#2a9d8f")
    for f in graph.factors_by_kind("association"):  # all replicas against the detections
        q = pos[f.name]
        ax.plot([q[0], q[0] - 0.6], [q[1], q[1] - 0.6], color="#b08900", lw=1.2, ls="--",
                zorder=1)
        ax.text(q[0] - 0.65, q[1] - 0.65, "all k", ha="right", va="top", fontsize=7,
                color="#b08900")
    for f in graph.factors_by_kind("conjugate"):  # the likelihood whose noise it sets
        for lik in parameterised(graph, f):
            ax.plot(*zip(pos[f.name], pos[lik], strict=True), color="#7b2cbf", lw=1.2,
                    ls=":", zorder=1)
    for f in graph.factors.values():
        for v in f.variables:
            ax.plot(*zip(pos[f.name], pos[v], strict=True), color="#444", lw=1.2, zorder=1)
        if f.kind == "likelihood":
            ax.plot(*zip(pos[f.name], pos[f"z:{f.name}"], strict=True), color="#444", lw=1.2,
                    zorder=1)
            ax.add_patch(Circle(pos[f"z:{f.name}"], 0.3, fc="#adb5bd", ec="k", zorder=2))
            ax.text(*pos[f"z:{f.name}"], "z", ha="center", va="center", fontsize=9, zorder=3)
        if f.kind == "transition":
            p = pos[f.name]
            ax.add_patch(FancyArrowPatch(p + np.array([0.55, 0.25]), p + np.array([0.15, 0.05]),
                                         connectionstyle="arc3,rad=-0.6", arrowstyle="->",
                                         mutation_scale=10, color="#1d3557", zorder=1))
            order = getattr(f, "order", 1)
            ax.text(p[0] + 0.6, p[1] + 0.3, f"t-1..t-{order}" if order > 1 else "t-1",
                    fontsize=7, color="#1d3557")
    for f in graph.factors.values():
        p = pos[f.name]
        ax.add_patch(Rectangle(p - s_fac / 2, s_fac, s_fac, fc=KIND_COLOURS[f.kind], ec="k",
                               zorder=3))
        label = type(f).__name__
        if f.kind == "likelihood" and label.endswith("Likelihood") and label != "Likelihood":
            label = label[:-len("Likelihood")]  # the colour already says "likelihood"
        if f.kind == "interaction":  # on the plate's edge: label outside it
            ax.text(p[0] - 0.2, p[1] + 0.25, label, ha="right", va="bottom", fontsize=7,
                    zorder=4)
        elif f.kind == "association":  # on the plate's left edge: label outside it
            ax.text(p[0] - 0.22, p[1] + 0.05, label, ha="right", va="center", fontsize=7,
                    zorder=4)
        elif f.kind == "prior" and len(f.variables) == 1:
            # up-left of its variable: the label left of it, clear of the variable's name
            # and of the transition's label above the variable
            ax.text(p[0] - 0.22, p[1], label, ha="right", va="center", fontsize=7, zorder=4)
        else:
            ax.text(p[0], p[1] - 0.32, label, ha="center", va="top", fontsize=7, zorder=4)
    for v in graph.variables.values():
        p = pos[v.name]
        ax.add_patch(Circle(p, r_var, fc=ROLE_COLOURS[v.role], ec="k", lw=1.5, zorder=3))
        ax.text(p[0], p[1] + 0.06, v.name, ha="center", va="center", fontsize=9,
                weight="bold", zorder=4)
        ax.text(p[0], p[1] - 0.2, f"{v.role}, d={v.dim}", ha="center", va="center",
                fontsize=6, zorder=4)
    ax.set_aspect("equal")
    ax.autoscale_view()
    xs = np.array([p[0] for p in pos.values()])
    ys = np.array([p[1] for p in pos.values()])
    left = 3.2 if graph.factors_by_kind("association") else 1.5
    ax.set_xlim(xs.min() - left, xs.max() + (2.4 if graph.plates else 1.8))
    ax.set_ylim(ys.min() - 1.0, ys.max() + (1.6 if graph.plates else 1.0))
    ax.axis("off")
    kinds = sorted({f.kind for f in graph.factors.values()})
    handles = [Rectangle((0, 0), 1, 1, fc=KIND_COLOURS[k], ec="k") for k in kinds]
    ax.legend(handles, kinds, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7,
              frameon=False)  # beside the drawing, never over it
    ax.set_title(title or graph.name)
    if own_fig and path is not None:
        fig.savefig(path, bbox_inches="tight", dpi=120)
        plt.close(fig)
    return ax
