"""Every model config: builds, saves as data, runs on the engine, reads out boxes."""

import dataclasses

import numpy as np
import pytest

from pgm import FactorGraph, FrameContext
from pgm.core.readout import Targets, readout
from pgm.inference import Engine
from pgm.inference.settings import EngineSettings
from pgm.models import get_config, get_model, model_names
from pgm.observation.detections import Detections
from pgm.synthetic import demo_scene, multi_target_scene

CONFIGS = {n: get_config(n) for n in model_names()}
SINGLE = sorted(n for n, c in CONFIGS.items() if c.kind == "single-object")
MULTI = sorted(n for n, c in CONFIGS.items() if c.kind == "multi-target")


@pytest.fixture(scope="module")
def walker():
    seq = demo_scene(seed=0, n_frames=6)
    x, y, w, h = seq.box(0, 1)
    return seq, (x + w / 2, y + h / 2, w, h)


def _graph(name, box=None):
    module = get_model(name)
    if name in SINGLE:
        return module.build_graph(module.Params(init_box=box))
    if "area" in {f.name for f in dataclasses.fields(module.Params)}:
        return module.build_graph(module.Params(area=320.0 * 240.0))
    if "motion" in {f.name for f in dataclasses.fields(module.Params)}:  # gpdm: no file here
        return module.build_graph(module.Params(motion="cv3"))
    return module.build_graph(module.Params())  # a plate: one sub-graph per target


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_model_saves_as_data_and_names_typed_settings(name, tmp_path, walker):
    graph = _graph(name, walker[1])
    graph.save(tmp_path / "model.json")
    assert FactorGraph.load(tmp_path / "model.json") == graph
    EngineSettings.from_dict(graph.meta.get("engine"))  # only known, valid settings
    graph.draw(tmp_path / "graph.dot")
    assert (tmp_path / "graph.dot").read_text().startswith("graph")


@pytest.mark.parametrize("name", SINGLE)
def test_single_object_model_reads_out_one_box_near_the_walker(name, walker):
    seq, box = walker
    eng = Engine(_graph(name, box), np.random.default_rng(0))
    for f in range(1, 4):
        rec = eng.step(FrameContext(f, seq.frames[f - 1]))
    targets = readout(eng.graph, rec)
    assert isinstance(targets, Targets) and len(targets) == 1
    truth = seq.box(0, 3)
    centre = targets.boxes[0, :2] + targets.boxes[0, 2:] / 2
    assert np.linalg.norm(centre - (truth[:2] + truth[2:] / 2)) < 0.5 * truth[3]


@pytest.mark.parametrize("name", MULTI)
def test_multi_target_model_reads_out_boxes_with_identities(name):
    seq = multi_target_scene(seed=0, n_frames=12)
    dets = seq.detections(np.random.default_rng(0), p_detect=1.0, sigma=1.0, clutter_rate=0.0)
    eng = Engine(_graph(name), np.random.default_rng(0))
    for f in range(1, 13):
        rows = dets[dets[:, 0] == f]
        rec = eng.step(FrameContext(f, seq.frames[f - 1],
                                    detections=Detections(rows[:, 1:5], rows[:, 5])))
    targets = readout(eng.graph, rec)
    n_true = len(seq.boxes_at(12)[0])
    assert len(targets) >= 1 and len(targets) <= n_true + 1
    assert len(np.unique(targets.ids)) == len(targets)
    assert np.all(targets.boxes[:, 2:] > 0)
    assert np.all((targets.scores >= 0) & (targets.scores <= 1))
