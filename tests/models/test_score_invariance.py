"""The multi-target cores read detection scores only through what they say about the
detections: on every shared MOT sequence, scores through any strictly increasing map
(probability, logit, rank, affine, power) give the same tracks.

Tolerance: none — the tracks (frames, identities, boxes) are identical. The maps are
strictly increasing in exact arithmetic; on each sequence the test first checks that the
mapped scores keep the original's order and ties in floating point too (a map that
rounds two distinct scores to one number has changed the detections, and no tracker
could be held to that)."""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pgm.evaluation.perturb import SCORE_KINDS, score_transform
from pgm.io.annotations import MotTable
from pgm.observation.detections import PublicDetections

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

pytestmark = [pytest.mark.data, pytest.mark.slow]

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11", "PETS09-S2L1-video")


def _detections(shared_data, name):
    from pgm.io.video import open_source

    if not (shared_data / name).is_dir():
        pytest.fail(f"{name} is not in ../shared/data")
    src = open_source(shared_data / name)
    return PublicDetections(shared_data / name / "det" / "det.txt"), src


def _mapped(det: PublicDetections, kind: str) -> PublicDetections:
    t = det.table
    s = score_transform(t.conf, kind)
    # the map keeps the scores' order and ties in floating point
    order = np.argsort(t.conf, kind="stable")
    assert np.array_equal(np.argsort(s, kind="stable"), order), kind
    assert np.array_equal(np.diff(t.conf[order]) > 0, np.diff(s[order]) > 0), kind
    return PublicDetections(MotTable(t.frames, t.ids, t.boxes, s))


def _tracks(graph, det, n, images=None):
    from classic_trackers import run_graph

    table, _, _ = run_graph(graph, det, n, images=images)
    return table


def _same(a, b, what):
    assert np.array_equal(a.frames, b.frames), what
    assert np.array_equal(a.ids, b.ids), what
    np.testing.assert_array_equal(a.boxes, b.boxes, err_msg=str(what))


@pytest.mark.parametrize("name", SEQUENCES)
def test_the_cores_with_learned_scores_give_the_same_tracks_under_any_score_map(
        shared_data, name):
    """``sort``, ``bytetrack``, ``ocsort``, ``botsort``, ``cbiou``, ``vb-sort`` and
    ``ocsort-colour``'s core (colour aside), each with the learned score map, and ``ocsort``
    with the quantile map, plain, gated and rebased by the detections found again, and
    placed by its own tracks (over the gated and the rebased quantile), on the whole
    sequence."""
    from pgm.models import botsort, bytetrack, cbiou, ocsort, ocsort_colour, sort, vb_sort

    det, src = _detections(shared_data, name)
    n = len(src)
    cores = [("sort", sort, {}), ("bytetrack", bytetrack, {}), ("ocsort", ocsort, {}),
             ("botsort", botsort, {}), ("cbiou", cbiou, {}), ("vb-sort", vb_sort, {}),
             ("ocsort-colour", ocsort_colour, {"appearance": None}),
             ("ocsort quantile", ocsort, {"score_map": "quantile"}),
             ("ocsort quantile-gated", ocsort, {"score_map": "quantile-gated"}),
             ("ocsort quantile-rebased", ocsort, {"score_map": "quantile-rebased"}),
             ("ocsort placed", ocsort, {"score_map": "placed"}),
             ("ocsort placed-rebased", ocsort, {"score_map": "placed-rebased"}),
             ("ocsort placed-over", ocsort, {"score_map": "placed-over"})]
    for label, module, extra in cores:
        p = replace(module.Params(), fps=float(src.fps), **{"score_map": "learned", **extra})
        graph = module.build_graph(p)
        ref = _tracks(graph, det, n)
        assert len(ref) > 0
        for kind in SCORE_KINDS:
            _same(_tracks(graph, _mapped(det, kind), n), ref, (label, kind))


@pytest.mark.parametrize("name", SEQUENCES)
def test_the_default_gives_the_same_tracks_under_any_score_map(shared_data, name):
    """The multi-target default as ``pgm track`` builds and runs it for the sequence
    (:func:`pgm.app.runner.track_multi`: the frames decoded for its colour models, the
    camera's motion estimated), on its first 60 frames; and the PHD and VB-PHD filters with
    the learned score model."""
    from pgm.app.runner import track_multi
    from pgm.io.video import open_source
    from pgm.models import DEFAULT_MULTI_TARGET, get_config
    from pgm.models.config import VideoInfo

    det, src = _detections(shared_data, name)
    for model in (DEFAULT_MULTI_TARGET, "phd", "vb-phd"):
        config = get_config(model)
        ref = None
        for kind in ("none",) + SCORE_KINDS:
            d = det if kind == "none" else _mapped(det, kind)
            video = VideoInfo(*src.size, fps=src.fps, score_range=d.score_range,
                              typical_height=float(np.median(d.table.boxes[:, 3])))
            graph = config.graph_for({}, video)
            reads = [f.score_map for f in graph.factors.values() if hasattr(f, "score_map")] + [
                f.scores.model for f in graph.factors.values()
                if hasattr(f, "scores") and hasattr(f.scores, "model")]
            assert reads in (["placed-over"], ["learned"]), reads
            result = track_multi(open_source(shared_data / name), graph, d, rng=0,
                                 write_video=False, progress=False, max_frames=60)
            table = result.table
            if ref is None:
                ref = table
                assert len(ref) > 0
            else:
                _same(table, ref, (model, kind))
