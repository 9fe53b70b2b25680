"""The default single-object model's calibrated confidence: in tracks.txt and
metrics.json, and it drops when the object is hidden."""

import json

import numpy as np
import pytest

from pgm.app.runner import track
from pgm.core.readout import check_confidence_spec, confidence
from pgm.io.annotations import SingleTrack, load_mot
from pgm.models import colour_pf, single_object
from tests.pgm.observation.test_correlation import scene


def hidden_object_frames(n_seen=12, n_hidden=6):
    """A textured object drifting right, then covered by a flat grey patch."""
    rng = np.random.default_rng(5)
    frames, boxes = [], []
    for k in range(n_seen + n_hidden):
        cx = 110.0 + 1.5 * k
        img = scene(rng, (cx, 100))
        if k >= n_seen:
            img[62:138, 80:170] = 128
        frames.append((k + 1, np.repeat(img[:, :, None], 3, axis=2)))
        boxes.append([cx - 20, 100 - 28, 40, 56])
    return frames, SingleTrack(np.arange(1, len(frames) + 1), np.array(boxes, float))


def test_confidence_is_written_and_drops_when_the_object_is_hidden(tmp_path):
    frames, gt = hidden_object_frames()
    graph = single_object.build_graph(single_object.Params(init_box=(110.0, 100, 40, 56)))
    res = track(frames, graph, rng=np.random.default_rng(0), out_dir=tmp_path, gt=gt,
                write_video=False, progress=False)
    s = res.scores
    assert s.shape == (len(frames),) and np.all((s >= 0) & (s <= 1))
    assert s[1:12].mean() > 0.8 and s[13:].mean() < s[1:12].mean() - 0.3
    table = load_mot(tmp_path / "tracks.txt", kind="det")
    np.testing.assert_allclose(table.conf, s, atol=1e-3)
    conf = json.loads((tmp_path / "metrics.json").read_text())["confidence"]
    assert conf["frames"] == list(range(1, len(frames) + 1))
    np.testing.assert_allclose(conf["values"], s)
    assert conf["calibration"]["n"] == len(frames)
    assert 0 <= conf["calibration"]["ece"] <= 1


def test_models_without_a_confidence_report_one_and_bad_declarations_are_refused():
    frames, _ = hidden_object_frames(3, 0)
    graph = colour_pf.build_graph(colour_pf.Params(init_box=(110.0, 100, 40, 56)))
    res = track(frames, graph, rng=np.random.default_rng(0), progress=False)
    np.testing.assert_array_equal(res.scores, 1.0)
    assert confidence(graph) is None
    factors = single_object.build_graph(single_object.Params(init_box=(9.0, 9, 4, 4))).factors
    name = next(iter(factors))
    for bad in ({"factor": "nope", "intercept": 0, "slope": 1},
                {"factor": name, "intercept": float("nan"), "slope": 1},
                {"factor": name, "intercept": 0}, "x"):
        with pytest.raises(ValueError, match="confidence"):
            check_confidence_spec(bad, factors)


def test_the_lost_signal_leaves_hidden_frames_empty_and_scores_itself(tmp_path, capsys):
    """``lost_below``: the frames whose confidence is under the threshold (the object
    hidden) are left out of tracks.txt, and metrics.json says how well that flags the
    frames where the box misses the object; a model without a confidence, or a threshold
    outside [0, 1], is a one-line error."""
    from pgm.app.runner import InputError

    frames, gt = hidden_object_frames()
    graph = single_object.build_graph(single_object.Params(init_box=(110.0, 100, 40, 56)))
    res = track(frames, graph, rng=np.random.default_rng(0), out_dir=tmp_path, gt=gt,
                write_video=False, progress=False, lost_below=0.5)
    table = load_mot(tmp_path / "tracks.txt", kind="det")
    np.testing.assert_array_equal(table.frames, res.frames[res.scores >= 0.5])
    assert 0 < len(table) < len(frames)
    assert all(f <= 13 for f in table.frames)  # the hidden frames (13-18) are empty
    lost = json.loads((tmp_path / "metrics.json").read_text())["lost"]
    assert lost["threshold"] == 0.5 and lost["flagged"] == int(np.sum(res.scores < 0.5))
    missed = np.asarray(res.metrics["ious"]) < 0.5
    if missed.any():
        assert 0 <= lost["recall"] <= 1
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["lost_below"] == 0.5 and run["frames_reported_lost"] == lost["flagged"]
    with pytest.raises(InputError, match="lost threshold"):
        track(frames, graph, rng=0, progress=False, lost_below=1.5)
    plain = colour_pf.build_graph(colour_pf.Params(init_box=(110.0, 100, 40, 56)))
    with pytest.raises(InputError, match="no calibrated confidence"):
        track(frames, plain, rng=0, progress=False, lost_below=0.5)


def test_the_response_feature_enters_the_logistic():
    """A declaration with ``response_slope`` adds it times the factor's log relative
    response (``confidence_response``: the response at the estimate over the running
    peak) to the logistic's argument, exactly; a non-finite slope is refused."""
    from pgm.core.frame import FrameContext
    from pgm.core.readout import posterior_spread
    from pgm.inference import Engine

    frames, _ = hidden_object_frames(8, 4)
    graph = single_object.build_graph(single_object.Params(init_box=(110.0, 100, 40, 56)))
    spec = dict(graph.meta["confidence"])
    graph.meta["confidence"] = {**spec, "response_slope": 1.5}
    eng = Engine(graph, np.random.default_rng(0))
    for frame in frames:
        rec = eng.step(FrameContext(*frame))
    cf = eng.graph.factors[spec["factor"]]
    z = (spec["intercept"] + spec["slope"] * cf.confidence_feature
         + spec["spread_slope"] * np.log(posterior_spread(rec, "object"))
         + 1.5 * cf.confidence_response)
    assert confidence(eng.graph, rec) == pytest.approx(1 / (1 + np.exp(-z)), rel=1e-12)
    assert cf.confidence_response == pytest.approx(np.log(max(cf.last_response, 1e-2)))
    assert cf.confidence_response < -0.5  # hidden: well below the running peak
    with pytest.raises(ValueError, match="response_slope"):
        check_confidence_spec({**spec, "response_slope": float("inf")}, eng.graph.factors)
