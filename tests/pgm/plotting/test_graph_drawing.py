"""Drawings that teach (pgm.plotting.graph_drawing): no two labels of any built-in
model's drawing overlap (measured on the rendered text boxes), a conjugate factor sits
between its noise node and the likelihood it parameterises and is linked to it, and a
factor between replicas (association, interaction) sits on the plate's edge."""

import itertools
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pgm.models import get_config, model_names  # noqa: E402
from pgm.plotting.graph_drawing import draw, layout, parameterised, plate_boxes  # noqa: E402


def _graph(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return get_config(name).example_graph({})[0]


@pytest.mark.parametrize("name", model_names())
def test_no_two_labels_overlap(name):
    graph = _graph(name)
    pos = layout(graph)
    xs = np.array([p[0] for p in pos.values()])
    ys = np.array([p[1] for p in pos.values()])
    fig, ax = plt.subplots(figsize=(max(4.0, np.ptp(xs) * 1.2 + 3),
                                    max(3.5, np.ptp(ys) * 1.2 + 2.5)))  # as draw() sizes it
    try:
        draw(graph, ax=ax)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in ax.texts
                 if t.get_text().strip()]
        assert len(boxes) >= len(graph.variables) + len(graph.factors)
        clashes = [(a, b) for (a, ba), (b, bb) in itertools.combinations(boxes, 2)
                   if ba.overlaps(bb)]
        assert not clashes, f"{name}: labels overlap: {clashes}"
    finally:
        plt.close(fig)


@pytest.mark.parametrize("name", ["vb-phd", "vb-sort"])
def test_a_conjugate_factor_sits_between_its_noise_and_its_likelihood(name):
    graph = _graph(name)
    pos = layout(graph)
    (vb,) = graph.factors_by_kind("conjugate")
    liks = parameterised(graph, vb)
    assert liks
    midpoint = 0.5 * (pos[vb.variables[0]] + np.mean([pos[n] for n in liks], axis=0))
    np.testing.assert_allclose(pos[vb.name], midpoint)
    fig, ax = plt.subplots()
    try:
        draw(graph, ax=ax)
        dotted = [line for line in ax.lines if line.get_linestyle() == ":"]
        ends = {tuple(np.round(np.asarray(line.get_xydata())[-1], 6)) for line in dotted}
        assert all(tuple(np.round(pos[n], 6)) in ends for n in liks)  # linked to each
    finally:
        plt.close(fig)


@pytest.mark.parametrize("name", ["sort", "multi-pf"])
def test_a_factor_between_replicas_sits_on_the_plates_edge(name):
    graph = _graph(name)
    pos = layout(graph)
    (x0, y0, x1, y1), = plate_boxes(graph, pos)
    across = graph.factors_by_kind("association") + graph.factors_by_kind("interaction")
    assert across
    for f in across:
        x, y = pos[f.name]
        on_edge = np.isclose(x, x0) or np.isclose(x, x1) or np.isclose(y, y0) or \
            np.isclose(y, y1)
        assert on_edge, (f.name, (x, y), (x0, y0, x1, y1))
