"""A round with ``"update": false``: its match keeps a track matched (a hit) without
updating the track's state, its last box or its observation history."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgm.core.frame import FrameContext
from pgm.factors.association import DetectionAssociation
from pgm.inference import Engine
from pgm.models import ocsort, sort
from pgm.observation.detections import Detections

CONFIDENT = {"iou": 0.3, "min_score": 0.6}


def _frame(t, boxes, scores):
    return FrameContext(t, detections=Detections(np.asarray(boxes, dtype=float).reshape(-1, 4),
                                                 np.asarray(scores, dtype=float)))


def _run(low_round, last):
    """A person walking five frames (confident detections), then frame 6 as ``last``
    (boxes, scores); the engine after it and frame 6's record."""
    params = sort.Params(fps=30.0, rounds=(CONFIDENT, low_round) if low_round else (CONFIDENT,),
                         activation=0.6)
    eng = Engine(sort.build_graph(params), 0)
    for t in range(1, 6):
        eng.step(_frame(t, [[100.0 + 4 * t, 80.0, 40.0, 100.0]], [0.9]))
    return eng, eng.step(_frame(6, *last))


def test_presence_match_keeps_the_track_without_moving_it():
    low = [[124.0 + 8.0, 86.0, 40.0, 100.0]]  # the low box, off the person's path
    coast, _ = _run(None, ([], []))  # no detection at frame 6: the prediction alone
    presence, record = _run({"iou": 0.3, "max_score": 0.6, "update": False}, (low, [0.3]))
    info = record.info["association"]  # what a step-through shows
    assert info.presence.tolist() == [True] and info.matched.tolist() == [0.0]
    pulled, record = _run({"iou": 0.3, "max_score": 0.6}, (low, [0.3]))
    assert record.info["association"].presence is None
    (tc,), (tp,), (tu,) = coast.tracks, presence.tracks, pulled.tracks
    assert tc.misses == 1 and tp.misses == 0 and tu.misses == 0  # a hit, not a miss
    mean = presence.beliefs["box"].mean()
    np.testing.assert_array_equal(mean, coast.beliefs["box"].mean())  # not updated
    np.testing.assert_array_equal(presence.beliefs["box"].cov(), coast.beliefs["box"].cov())
    assert np.abs(pulled.beliefs["box"].mean()[0, :2] - mean[0, :2]).max() > 1.0  # updated
    np.testing.assert_array_equal(tp.state, tc.state)  # the last box: frame 5's
    assert not np.array_equal(tu.state, tc.state)


def test_presence_match_leaves_the_observation_history():
    """OC-SORT keeps each track's observations for its momentum and re-update: a presence
    match adds none."""
    from pgm.inference.association import TrackState

    low = [[124.0 + 8.0, 86.0, 40.0, 100.0]]
    histories = []
    for update in (False, True):
        rounds = ocsort.Params().rounds + ({"iou": 0.3, "max_score": 0.6, "update": update},)
        p = ocsort.Params(fps=30.0, rounds=rounds, activation=0.6, min_hits=1)
        eng = Engine(sort.build_graph(p), 0)
        for t in range(1, 6):
            eng.step(_frame(t, [[100.0 + 4 * t, 80.0, 40.0, 100.0]], [0.9]))
        eng.step(_frame(6, low, [0.3]))
        h = eng.replicas.state[0].get("box", TrackState)
        assert isinstance(h, TrackState) and eng.tracks[0].misses == 0
        histories.append(h.observations)
    kept, added = histories
    assert max(kept.boxes) == kept.age - 1  # frame 5's detection is the newest
    assert max(added.boxes) == added.age
    np.testing.assert_array_equal(added.boxes[added.age][:2], [152.0, 136.0])  # its centre


def test_update_key_is_saved_and_checked():
    rounds = [CONFIDENT, {"iou": 0.5, "max_score": 0.6, "update": False}]
    f = DetectionAssociation("box", rounds=rounds)
    assert f.presence_rounds == (1,)
    p = json.loads(json.dumps(f.params()))
    assert p["rounds"][1]["update"] is False and "update" not in p["rounds"][0]
    assert DetectionAssociation("box", **p).rounds == f.rounds
    with pytest.raises(ValueError, match="'update' is true or false"):
        DetectionAssociation("box", rounds=[{"iou": 0.3, "update": "no"}])


def test_default_has_the_presence_round_and_a_threshold_moves_its_split():
    """The multi-target default: OC-SORT's rounds on the gated quantile at 0.2, then the
    presence round on (0, 0.2) for tracks matched in the previous frame; a
    ``score_threshold`` moves the split and keeps the band's floor above the gate; a
    threshold not above that floor leaves no band."""
    from pgm.models import ocsort_colour

    r = ocsort_colour.build_graph(ocsort_colour.Params()).factors["association"].rounds
    assert [(x["min_score"], x["max_score"], x["update"]) for x in r] == [
        (0.2, np.inf, True), (0.2, np.inf, True), (ocsort_colour.ABOVE_GATE, 0.2, False)]
    assert r[2]["tracks"] == "tracked" and r[2]["iou"] == 0.5
    r = ocsort_colour.build_graph(ocsort_colour.Params(score_threshold=0.4)
                                  ).factors["association"].rounds
    assert [(x["min_score"], x["max_score"]) for x in r] == [
        (0.4, np.inf), (0.4, np.inf), (ocsort_colour.ABOVE_GATE, 0.4)]
    assert len(sort.with_score_threshold(ocsort_colour.rounds(), 0.0)) == 2


def test_presence_match_reports_the_estimate_where_a_track_reports_its_detection():
    """A model that reports a matched track's detection (``report="detection"``) reports
    a presence-matched track at its estimate (its box there is an earlier detection's)."""
    from pgm.core.readout import readout

    low = [[124.0 + 8.0, 86.0, 40.0, 100.0]]
    p = sort.Params(fps=30.0, rounds=(CONFIDENT, {"iou": 0.3, "max_score": 0.6,
                                                  "update": False}), activation=0.6)
    eng = Engine(sort.build_graph(p), 0)
    for t in range(1, 6):
        eng.step(_frame(t, [[100.0 + 4 * t, 80.0, 40.0, 100.0]], [0.9]))
    targets = readout(eng.graph, eng.step(_frame(6, low, [0.3])))
    (track,) = eng.tracks
    assert track.matched and not track.located and len(targets.ids) == 1
    x, y, w, h = targets.boxes[0]  # on the walk's prediction (124, 80), not the low box
    assert abs(x - 124.0) < 1.0 and abs(y - 80.0) < 1.0
    np.testing.assert_allclose([w, h], [40.0, 100.0])
    assert abs(x - 132.0) > 7.0 and abs(x - 120.0) > 3.0  # nor frame 5's detection
