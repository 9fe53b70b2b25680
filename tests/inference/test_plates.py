"""Plates: K = 1 is the single-target engine bit for bit, K independent replicas are K
separate runs, mutual exclusion separates replicas started on one target, births and
deaths from detections, the declaration saves and draws."""

from __future__ import annotations

import numpy as np
import pytest

from pgm import FactorGraph, Lifecycle, MutualExclusion, Plate
from pgm.core.frame import FrameContext
from pgm.inference import Engine
from pgm.inference.batched import ReplicaRNG
from pgm.models import colour_pf, multi_pf, part_graph
from pgm.observation.detections import Detections
from pgm.synthetic.scene import ObjectSpec, Scene
from pgm.synthetic.scenes import multi_target_scene

N = 40


def _plated(graph: FactorGraph, *extra) -> FactorGraph:
    """The same declaration with every variable in a plate (and ``extra`` factors)."""
    return FactorGraph(list(graph.variables.values()), list(graph.factors.values()) + list(extra),
                       name=graph.name, meta=graph.meta,
                       plates=[Plate("target", tuple(graph.variables))])


@pytest.fixture(scope="module")
def scene():
    return multi_target_scene(seed=3, n_frames=30, n_objects=3, occluder=False)


def _box(scene, obj: int, frame: int = 1) -> np.ndarray:
    x, y, w, h = scene.box(obj, frame)
    return np.array([x + w / 2, y + h / 2, w, h])


def _run_single(graph, scene, seed, frames):
    eng = Engine(graph, np.random.default_rng(seed), num_particles=N)
    out = []
    for f in frames:
        rec = eng.step(FrameContext(f, scene.frames[f - 1]))
        out.append({v: rec.estimates[v] for v in graph.variables})
    return out, eng


def _run_plate(graph, scene, boxes, seeds, frames):
    eng = Engine(graph, np.random.default_rng(99), num_particles=N)
    out = []
    for i, f in enumerate(frames):
        ctx = FrameContext(f, scene.frames[f - 1])
        if i == 0:
            eng.add(np.asarray(boxes), ctx, rngs=[np.random.default_rng(s) for s in seeds])
            est = {v: eng.replicas.est[v] for v in graph.variables}
        else:
            est = eng.step(ctx, lifecycle=False).estimates
        out.append(est)
    return out, eng


@pytest.mark.parametrize("n_parts", [1, 2])
def test_one_replica_is_the_single_target_engine_bit_for_bit(scene, n_parts):
    box = _box(scene, 0)
    graph = part_graph.build_graph(part_graph.Params(init_box=tuple(box), n_parts=n_parts,
                                                     num_particles=N, scale_noise=0.01,
                                                     jump_prob=0.2))
    frames = range(1, 21)
    single, eng1 = _run_single(graph, scene, 7, frames)
    plate, eng2 = _run_plate(_plated(graph), scene, [box], [7], frames)
    for s, p in zip(single, plate, strict=True):
        for v in graph.variables:
            assert np.array_equal(s[v], p[v][0]), v
    for v in graph.variables:
        b = eng2.beliefs[v]
        assert np.array_equal(eng1.beliefs[v].x, b.x[0])
        assert np.array_equal(eng1.beliefs[v].log_weights, b.log_weights[0])


@pytest.mark.parametrize("cue", ["template", "colour+contrast"])
def test_independent_replicas_are_separate_runs(scene, cue):
    """Three replicas against three runs of the single-target engine with the same
    generators: equal to the last bit where each replica's likelihood is its own call."""
    boxes = [_box(scene, k) for k in range(2)] + [_box(scene, 0) + [5, 5, 0, 0]]
    seeds = [11, 12, 13]
    frames = range(1, 16)
    template = colour_pf.build_graph(colour_pf.Params(init_box=tuple(boxes[0]),
                                                      num_particles=N, jump_prob=0.3,
                                                      appearance=cue))
    # per-target noise in pixels differs with the box: use relative noise, shared
    g = FactorGraph(list(template.variables.values()), [
        f if f.kind != "transition" else type(f)("object", noise_std=[0.03, 0.03, 0, 0],
                                                 damping=0.5, relative=True,
                                                 jump_prob=0.3, jump_scale=10.0)
        for f in template.factors.values()], name="pf", meta=template.meta)
    plate, _ = _run_plate(_plated(g), scene, boxes, seeds, frames)
    for k, (box, seed) in enumerate(zip(boxes, seeds, strict=True)):
        gk = FactorGraph(list(g.variables.values()), [
            f if f.kind != "prior" else f.born_at(dict(zip("cx cy w h".split(), box,
                                                           strict=True)), ("cx", "cy", "w", "h"))
            for f in g.factors.values()], name="pf", meta=g.meta)
        single, _ = _run_single(gk, scene, seed, frames)
        for s, p in zip(single, plate, strict=True):
            if cue == "template":
                np.testing.assert_array_equal(s["object"], p["object"][k])
            else:  # colour histograms of all replicas are scored in one batched pass,
                # which sums the Bhattacharyya terms in another order (last-bit rounding)
                np.testing.assert_allclose(s["object"], p["object"][k], rtol=1e-9)


def _twins(n_frames=25):
    """Two identical objects side by side, moving together."""
    cols = ((40, 40, 200), (200, 60, 40))
    objs = [ObjectSpec(box=(100, 80, 30, 70), colors=cols, velocity=(1.0, 0.0), name="a"),
            ObjectSpec(box=(138, 80, 30, 70), colors=cols, velocity=(1.0, 0.0), name="b")]
    return Scene(objs, [], size=(320, 240), fps=30.0).render(np.random.default_rng(0), n_frames)


@pytest.mark.parametrize("strength", [0.0, 30.0])
def test_mutual_exclusion_separates_two_replicas_on_one_target(strength):
    seq = _twins()
    p = multi_pf.Params(num_particles=200, exclusion=strength, detection_strength=0.0, fps=1.0,
                        pos_noise=0.08, scale_noise=0.0, damping=0.0)
    g = multi_pf.build_graph(p)
    eng = Engine(g, np.random.default_rng(0))
    a = seq.box(0, 1)
    start = np.array([a[0] + a[2] / 2, a[1] + a[3] / 2, a[2], a[3]])
    eng.add(np.stack([start, start + [1, 0, 0, 0]]), FrameContext(1, seq.frames[0]))
    iou = []
    for f in range(2, seq.n_frames + 1):
        rec = eng.step(FrameContext(f, seq.frames[f - 1]), lifecycle=False)
        b = rec.plate.boxes
        iou.append(float(multi_pf_iou(b[0], b[1])))
    late = np.mean(iou[-10:])
    if strength == 0:
        assert late > 0.6, iou  # without exclusion both stay on the same object
    else:
        assert late < 0.2, iou  # with it, they part
        b = rec.plate.boxes
        truth = [seq.box(k, seq.n_frames) for k in range(2)]
        truth = [np.array([t[0] + t[2] / 2, t[1] + t[3] / 2, t[2], t[3]]) for t in truth]
        best = sorted(max(multi_pf_iou(b[i], t) for t in truth) for i in range(2))
        assert best[0] > 0.5, best  # ... and the pushed one found the twin


def multi_pf_iou(a, b):
    from pgm.inference.plates import _iou

    return float(_iou(np.asarray(a, float), np.asarray(b, float)))


def test_births_and_deaths_from_detections(scene):
    """Replicas start on detections, get identities after confirm_hits matches, and are
    removed when their target's detections stop."""
    g = multi_pf.build_graph(multi_pf.Params(num_particles=30, lifecycle=Lifecycle(
        confirm_hits=2, max_coast=1, max_lost=3)))
    eng = Engine(g, np.random.default_rng(0))
    counts, reported = [], []
    for f in range(1, 13):
        ids, boxes = scene.boxes_at(f)
        if f > 6:  # the second target's detections stop
            keep = ids != ids.min() + 1
            boxes = boxes[keep]
        rec = eng.step(FrameContext(f, scene.frames[f - 1],
                                    detections=Detections(boxes, np.ones(len(boxes)))))
        counts.append(eng.num_targets)
        reported.append(int(rec.plate.reported.sum()))
    assert counts[0] == len(scene.boxes_at(1)[0])
    assert reported[0] == 0 and reported[2] == counts[2]  # confirmed at the 2nd match
    assert counts[-1] == counts[5] - 1  # the target without detections was removed
    ids = [t.track_id for t in eng.tracks]
    assert len(set(ids)) == len(ids) and None not in ids


def test_declaration_saves_loads_and_draws(tmp_path):
    g = multi_pf.build_graph(multi_pf.Params(n_parts=2))
    path = tmp_path / "m.json"
    g.save(path)
    h = FactorGraph.load(path)
    assert h == g and h.plates == g.plates
    dot = g.to_dot()
    assert "cluster" in dot and "K" in dot
    g.draw(tmp_path / "m.png")
    assert (tmp_path / "m.png").stat().st_size > 1000


def test_bad_plate_declarations():
    g = colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 20, 20)))
    v = list(g.variables.values())
    with pytest.raises(ValueError, match="unknown variable"):
        FactorGraph(v, list(g.factors.values()), plates=[Plate("t", ("nope",))])
    with pytest.raises(ValueError, match="in no plate"):
        FactorGraph(v, list(g.factors.values()) + [MutualExclusion("object")])
    with pytest.raises(ValueError, match="declares no plate"):
        Engine(g, np.random.default_rng(0)).add(None, FrameContext(1, np.zeros((8, 8, 3))))
    with pytest.raises(ValueError, match="plate lifecycle: max_lost"):
        Lifecycle(max_coast=5, max_lost=2)


def test_replica_rng_splits_draws_and_refuses_others():
    gens = [np.random.default_rng(s) for s in (1, 2)]
    r = ReplicaRNG(gens, 3)
    x = r.standard_normal((6, 2))
    ref = np.concatenate([np.random.default_rng(s).standard_normal((3, 2)) for s in (1, 2)])
    assert np.array_equal(x, ref)
    with pytest.raises(ValueError, match="leading axis"):
        r.standard_normal((4, 2))
    with pytest.raises(ValueError, match="cannot"):
        r.integers(3)


def test_per_replica_diagnostics_follow_births_and_deaths(scene):
    """After the associate stage every per-replica array of the step record has one row
    per replica, in the replicas' order (the plate's ids)."""
    g = multi_pf.build_graph(multi_pf.Params(num_particles=30, lifecycle=Lifecycle(
        confirm_hits=2, max_coast=1, max_lost=2)))
    eng = Engine(g, np.random.default_rng(0))
    sizes = set()
    for f in range(1, 13):
        ids, boxes = scene.boxes_at(f)
        if f > 6:  # one target's detections stop: its replica dies
            boxes = boxes[ids != ids.min() + 1]
        rec = eng.step(FrameContext(f, scene.frames[f - 1],
                                    detections=Detections(boxes, np.ones(len(boxes)))))
        k = eng.num_targets
        sizes.add(k)
        info = rec.info.get("person", {})
        assert rec.plate.ids.shape == (k,) and rec.estimates["person"].shape[0] == k
        for a in (rec.ess.get("person"), info.get("ess"), info.get("resampled"),
                  rec.resampled.get("person")):
            assert a is None or np.shape(a) == (k,), (f, np.shape(a), k)
    assert len(sizes) > 1  # replicas were born and removed
