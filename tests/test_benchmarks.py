"""The benchmarks' shared timing loop reports what the runner reports (same seed)."""

import sys
from pathlib import Path

import numpy as np

from pgm.app.runner import track
from pgm.inference import Engine
from pgm.models import single_object
from pgm.synthetic import demo_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _common import time_engine  # noqa: E402


def test_time_engine_boxes_equal_the_runner_boxes():
    seq = demo_scene(seed=0, n_frames=8)
    x, y, w, h = seq.box(0, 1)
    graph = single_object.build_graph(single_object.Params(init_box=(x + w / 2, y + h / 2, w, h)))
    frames = [(k + 1, img) for k, img in enumerate(seq.frames)]
    boxes, secs, _ = time_engine(Engine(graph, np.random.default_rng(3)), frames)
    result = track(frames, graph, rng=np.random.default_rng(3), progress=False)
    np.testing.assert_array_equal(boxes, result.boxes)
    assert secs > 0
