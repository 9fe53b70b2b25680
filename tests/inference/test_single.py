"""The engine's runtimes: one graph (:class:`pgm.inference.single.SingleGraph`) and a plate
(:class:`pgm.inference.plates.PlateRuntime`), chosen by the registry of
:mod:`pgm.inference.record`."""

import numpy as np
import pytest

from pgm.core.frame import FrameContext
from pgm.inference import Engine
from pgm.inference.plates import PlateRuntime
from pgm.inference.record import _RUNTIMES, register_runtime, runtime_for
from pgm.inference.single import SingleGraph
from pgm.models import linear_gaussian, multi_pf


def test_a_graph_without_a_plate_has_no_replicas():
    one = Engine(linear_gaussian.build_graph(linear_gaussian.Params()), rng=0,
                 num_particles=50)
    assert type(one.runtime) is SingleGraph and one.num_targets == 0 and one.tracks == []
    assert not one.predicts_missing_frames
    frame = FrameContext(0, measurements=np.array([0.1]))
    with pytest.raises(ValueError, match="declares no plate"):
        one.add(np.array([[5.0, 5, 2, 2]]), frame)
    with pytest.raises(ValueError, match="declares no plate"):
        one.remove([0])
    plate = Engine(multi_pf.build_graph(multi_pf.Params(num_particles=20)), rng=0)
    assert type(plate.runtime) is PlateRuntime and plate.predicts_missing_frames
    assert plate.plate is plate.graph.plates[0] and plate.num_targets == 0



def test_a_registered_runtime_runs_the_graphs_it_applies_to():
    """A runtime registered later is asked first; the plate's still serves plate graphs."""
    graph = linear_gaussian.build_graph(linear_gaussian.Params())
    calls = []

    class Counting(SingleGraph):
        def step_stages(self, engine, frame, record, lifecycle):
            calls.append(frame.index)
            yield from super().step_stages(engine, frame, record, lifecycle)

    mine = Counting()
    register_runtime(lambda g: g.name == graph.name, mine)
    try:
        assert runtime_for(graph) is mine
        eng = Engine(graph, rng=0, num_particles=50)
        ref = Engine(graph, rng=0, num_particles=50)
        ref.runtime = SingleGraph()
        for t in range(3):
            frame = FrameContext(t, measurements=np.array([0.2 * t]))
            np.testing.assert_array_equal(eng.step(frame).estimates["x"],
                                          ref.step(frame).estimates["x"])
        assert calls == [0, 1, 2]
        assert isinstance(runtime_for(multi_pf.build_graph(multi_pf.Params())), PlateRuntime)
    finally:
        _RUNTIMES[:] = [r for r in _RUNTIMES if r[1] is not mine]
    assert runtime_for(graph) is None
