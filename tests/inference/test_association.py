"""Data association of a plate's replicas (pgm.inference.association): the rounds of
``assign`` (pools, score splits, gates, buffers, fused scores, momentum) on hand-made
frames, and a replica's observation history."""

import numpy as np

from pgm.factors.association import DetectionAssociation
from pgm.inference.association import ObservationHistory, assign, direction_consistency
from pgm.inference.association_terms import AssociationInputs


def _rounds(*rounds):
    return DetectionAssociation("box", rounds=list(rounds)).plans


def _assign(pred, dets, scores, plans, **kw):
    return assign(AssociationInputs(pred, dets, np.asarray(scores, float)), plans, **kw)


def _box(cx, cy=50.0, w=10.0, h=20.0):
    return [cx, cy, w, h]


def test_one_round_is_the_gated_hungarian_assignment():
    pred = np.array([_box(0), _box(100), _box(200)])
    dets = np.array([_box(101), _box(2), _box(400)])
    a = _assign(pred, dets, np.ones(3), _rounds({"iou": 0.3}))
    assert sorted(zip(a.rows.tolist(), a.cols.tolist(), strict=True)) == [(0, 1), (1, 0)]
    assert a.iou.shape == (3, 3) and a.rounds.tolist() == [0, 0]


def test_rounds_split_detections_by_score_and_replicas_by_pool():
    pred = np.array([_box(0), _box(100)])
    dets = np.array([_box(1), _box(99)])
    scores = np.array([0.9, 0.2])
    rounds = _rounds({"iou": 0.3, "min_score": 0.5}, {"iou": 0.3, "max_score": 0.5})
    a = _assign(pred, dets, scores, rounds)
    assert dict(zip(a.rows.tolist(), a.rounds.tolist(), strict=True)) == {0: 0, 1: 1}
    # a round on the confirmed replicas only leaves the tentative one unmatched
    a = _assign(pred, dets, scores, _rounds({"iou": 0.3, "tracks": "confirmed"}),
               confirmed=np.array([True, False]), tracked=np.array([True, True]))
    assert a.rows.tolist() == [0]


def test_buffer_and_fused_score_change_what_passes_the_gate():
    pred = np.array([_box(0)])
    far = np.array([_box(12)])  # no overlap: a plain IoU gate refuses it
    assert len(_assign(pred, far, np.ones(1), _rounds({"iou": 0.1})).rows) == 0
    buffered = _assign(pred, far, np.ones(1), _rounds({"iou": 0.1, "buffer": 0.3}))
    assert buffered.rows.tolist() == [0]
    near = np.array([_box(2)])  # IoU 2/3: fused with a score of 0.5 it falls below 0.4
    assert len(_assign(pred, near, np.array([0.5]),
                      _rounds({"iou": 0.4, "fuse_score": True})).rows) == 0
    assert len(_assign(pred, near, np.array([0.5]), _rounds({"iou": 0.4})).rows) == 1


def test_momentum_term_prefers_the_detection_along_the_motion():
    ref = np.array([_box(0)])
    dets = np.array([_box(10), _box(-10)])
    velocity = np.array([[0.0, 1.0]])  # (dy, dx): moving right
    cost = direction_consistency(velocity, np.array([True]), ref, dets, np.ones(2))
    assert cost[0, 0] > cost[0, 1]
    np.testing.assert_allclose(cost[0], [0.5, -0.5], atol=1e-3)  # (π/2 - |angle|) / π
    unknown = direction_consistency(velocity, np.array([False]), ref, dets, np.ones(2))
    assert not unknown.any()


def test_observation_history_direction_over_delta_t():
    h = ObservationHistory(delta_t=2)
    assert h.previous(0) is None
    for t, x in enumerate([0.0, 3.0, 6.0]):
        h.age = t
        h.observe(np.array(_box(x)))
    np.testing.assert_allclose(h.velocity, [0.0, 1.0], atol=1e-6)
    np.testing.assert_array_equal(h.previous(2), _box(0.0))  # two frames back
    h.age = 5
    h.observe(np.array(_box(6.0, cy=56.0)))
    assert min(h.boxes) >= 3  # older observations than delta_t are dropped
