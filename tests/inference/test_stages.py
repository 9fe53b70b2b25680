"""Stepping through a frame (Engine.stages): a generator that yields after each stage
with the record as filled so far; step() is that generator run through, so both give the
same frames."""

import numpy as np

from pgm.core.frame import FrameContext
from pgm.inference import Engine
from pgm.models import linear_gaussian, sort
from pgm.observation.detections import Detections


def _frames(n=5):
    rng = np.random.default_rng(1)
    return [FrameContext(t + 1, measurements=rng.normal(0.1 * t, 0.7, 1)) for t in range(n)]


def test_stages_yield_the_schedule_and_step_is_their_end():
    g = linear_gaussian.build_graph(linear_gaussian.Params())
    stepped, walked = Engine(g, 0, num_particles=200), Engine(g, 0, num_particles=200)
    for t, frame in enumerate(_frames()):
        rec = stepped.step(frame)
        names, seen = [], {}
        for stage, partial in walked.stages(frame):
            names.append(stage)
            seen[stage] = (dict(partial.ess), dict(partial.estimates))
        phases = walked.schedule.first_frame if t == 0 else walked.schedule.phases
        assert names == [s for s, _ in phases] + ["done"]
        assert "x" in seen["weight"][0] and not seen["weight"][1]  # ESS now, no estimate yet
        assert "x" in seen["estimate"][1]
        np.testing.assert_array_equal(partial.estimates["x"], rec.estimates["x"])
        np.testing.assert_array_equal(walked.beliefs["x"].x, stepped.beliefs["x"].x)
    assert walked.t == stepped.t == 5


def test_a_plates_stages_end_with_the_association():
    g = sort.build_graph(sort.Params())
    eng = Engine(g, 0)
    names = []
    for f in range(1, 5):
        boxes = np.array([[10.0 + 2 * f, 20.0, 30.0, 60.0], [100.0, 40.0 + f, 30.0, 60.0]])
        frame = FrameContext(f, detections=Detections(boxes, np.full(2, 0.9)))
        names.append([s for s, _ in eng.stages(frame)])
    assert names[0][-2:] == ["associate", "done"]
    assert "predict" in names[-1] and names[-1][-2:] == ["associate", "done"]
    assert eng.num_targets >= 1


def test_a_frame_left_half_way_is_a_clear_error_and_a_failed_one_is_not():
    import pytest

    g = linear_gaussian.build_graph(linear_gaussian.Params())
    eng = Engine(g, 0, num_particles=100)
    frames = _frames(3)
    walk = eng.stages(frames[0])
    next(walk)  # the prior stage only
    with pytest.raises(ValueError, match="half-way"):
        eng.step(frames[1])
    for _ in walk:  # run to its end: the engine goes on
        pass
    eng.step(frames[1])
    bad = FrameContext(3, measurements=np.array([0.0, 1.0, 2.0]))  # wrong size: an error
    with pytest.raises(ValueError):
        eng.step(bad)
    assert eng.step(frames[2]).frame == 3  # an error ends the frame; the next one runs
