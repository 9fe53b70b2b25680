"""The association's extension points (pgm.inference.association_terms): terms and gates
of one's own in every round, the Mahalanobis gate on the predicted covariance checked
against a direct computation and on a jump IoU alone lets through, saved by name."""

import numpy as np
import pytest

from pgm import FactorGraph
from pgm.core.frame import FrameContext
from pgm.factors.association import DetectionAssociation
from pgm.inference import Engine
from pgm.inference.association_terms import mahalanobis_distances, mahalanobis_gate
from pgm.models import sort
from pgm.observation.detections import Detections


def prefer_second(inputs):
    """A user's term: +1 for the second detection (a stand-in for any learned score)."""
    out = np.zeros((len(inputs.pred), len(inputs.boxes)))
    out[:, 1:2] = 1.0
    return out


def _with(graph: FactorGraph, **kw) -> FactorGraph:
    old = graph.factors_by_kind("association")[0]
    new = DetectionAssociation(old.variables[0], **{**old.params(), **kw}, name=old.name)
    others = [f for f in graph.factors.values() if f.name != old.name]
    return FactorGraph(list(graph.variables.values()), others + [new], name=graph.name,
                       meta=graph.meta, plates=graph.plates)


def _frame(t, boxes_xywh):
    b = np.asarray(boxes_xywh, dtype=float).reshape(-1, 4)
    return FrameContext(t, detections=Detections(b, np.full(len(b), 0.9)))


def _walk(engine, n=8):
    for t in range(1, n + 1):
        engine.step(_frame(t, [100.0 + 2 * t, 50.0, 100.0, 200.0]))


def test_the_mahalanobis_distance_is_the_direct_computation():
    g = _with(sort.build_graph(sort.Params()), gates=[{"fn": mahalanobis_gate}])
    eng = Engine(g, 0)
    _walk(eng)
    seen = {}

    def spy(inputs, quantile=0.99):
        seen["inputs"] = inputs
        return mahalanobis_gate(inputs, quantile)

    import sys
    sys.modules[__name__].spy = spy  # a module-level name the factor can be saved by
    g2 = _with(g, gates=[{"fn": f"{__name__}:spy"}])
    eng2 = Engine(g2, 0)
    _walk(eng2)
    eng2.step(_frame(9, [[120.0, 50.0, 100.0, 200.0], [300.0, 80.0, 90.0, 180.0]]))
    inp = seen["inputs"]
    d2 = mahalanobis_distances(inp)
    lik = [f for f in g2.factors_of("box", "likelihood")][0]
    for k in range(len(inp.pred)):
        R = np.broadcast_to(lik.noise_cov(inp.mean[k:k + 1]), (1,) + lik.H.shape[:1] * 2)[0]
        S = lik.H @ inp.cov[k] @ lik.H.T + R
        from pgm.core.boxes import box_coding, encode_boxes
        z = encode_boxes(inp.boxes, box_coding(inp.labels))
        for j in range(len(inp.boxes)):
            nu = z[j] - lik.H @ inp.mean[k]
            assert d2[k, j] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-9)


def test_the_gate_refuses_a_jump_the_iou_lets_through():
    jump = [131.0, 50.0, 100.0, 200.0]  # 15 px past the prediction: IoU ~ 0.7
    runs = {}
    for name, graph in (("iou", sort.build_graph(sort.Params())),
                        ("gated", _with(sort.build_graph(sort.Params()),
                                        gates=[{"fn": mahalanobis_gate}]))):
        eng = Engine(graph, 0)
        _walk(eng)
        rec = eng.step(_frame(9, jump))
        runs[name] = (int(np.isfinite(rec.info["association"]["matched"]).sum())
                      if "association" in rec.info else None, eng.num_targets)
    assert runs["iou"][1] == 1  # matched: the one track followed the jump
    assert runs["gated"][1] == 2  # refused: the jump starts a new (tentative) track


def test_a_users_term_changes_which_detection_is_taken():
    two = [[118.0, 50.0, 100.0, 200.0], [124.0, 50.0, 100.0, 200.0]]  # both overlap well
    picks = {}
    for name, kw in (("iou", {}), ("term", {"terms": [{"fn": prefer_second, "weight": 1.0}]})):
        eng = Engine(_with(sort.build_graph(sort.Params()), **kw), 0)
        _walk(eng)
        eng.step(_frame(9, two))
        picks[name] = eng.assignment.cols.tolist()
    assert picks["iou"] == [0] and picks["term"] == [1]


def test_terms_and_gates_are_saved_by_name():
    g = _with(sort.build_graph(sort.Params()), gates=[{"fn": mahalanobis_gate,
                                                       "args": {"quantile": 0.95}}],
              terms=[{"fn": prefer_second, "weight": 0.5}])
    back = FactorGraph.from_dict(g.to_dict())
    f = back.factors_by_kind("association")[0]
    assert f.gates == [{"fn": "pgm.inference.association_terms:mahalanobis_gate",
                        "args": {"quantile": 0.95}}]
    assert f.terms == [{"fn": f"{__name__}:prefer_second", "args": {}, "weight": 0.5}]

    def local(inputs):
        return np.ones((len(inputs.pred), len(inputs.boxes)), bool)

    with pytest.raises(ValueError, match="module level"):
        _with(g, gates=[{"fn": local}])
    bad = _with(sort.build_graph(sort.Params()), gates=[{"fn": "no_such_mod:gate"}])
    eng = Engine(bad, 0)
    with pytest.raises(ValueError, match="no_such_mod"):
        _walk(eng, 2)


def test_a_rounds_own_gate_acts_in_that_round_only():
    """ByteTrack's rounds, the Mahalanobis gate added to the low-score round only: a
    low-score jump is refused there, a high-score one still taken by the first round."""
    from pgm.models import bytetrack

    base = bytetrack.build_graph(bytetrack.Params())
    rounds = base.factors_by_kind("association")[0].params()["rounds"]
    assert len(rounds) == 2
    gated_rounds = [rounds[0], {**rounds[1], "gates": [{"fn": mahalanobis_gate}]}]
    results = {}
    for name, graph in (("plain", base), ("gated", _with(base, rounds=gated_rounds))):
        for score in (0.95, 0.3):
            eng = Engine(graph, 0)
            _walk(eng)
            b = np.array([[131.0, 50.0, 100.0, 200.0]])
            eng.step(FrameContext(9, detections=Detections(b, np.array([score]))))
            results[(name, score)] = len(eng.assignment.rows)
    assert results[("plain", 0.3)] == 1 and results[("gated", 0.3)] == 0
    assert results[("plain", 0.95)] == 1 and results[("gated", 0.95)] == 1
    back = FactorGraph.from_dict(_with(base, rounds=gated_rounds).to_dict())
    saved = back.factors_by_kind("association")[0].params()["rounds"]
    assert "gates" not in saved[0] and saved[1]["gates"][0]["fn"].endswith(":mahalanobis_gate")


def centre_affinity(inputs, scale=1.0):
    """A user's affinity: ``exp(-d / (scale × mean width))`` of the centres' distance ``d``
    (matches boxes that do not overlap, as IoU cannot)."""
    d = np.linalg.norm(inputs.pred[:, None, :2] - inputs.boxes[None, :, :2], axis=2)
    w = 0.5 * (inputs.pred[:, None, 2] + inputs.boxes[None, :, 2])
    return np.exp(-d / (scale * w))


def _crossing_stream(n=40, seed=3):
    """Four walkers (two crossing; the first stops at frame 15 and is unseen for the next
    seven, so that only its last detection finds it again), scores in [0.3, 1), a
    detection missed now and then."""
    rng = np.random.default_rng(seed)
    starts = np.array([[50.0, 100.0, 6.0, 0.0], [400.0, 110.0, -4.0, 0.0],
                       [100.0, 300.0, 1.0, 1.0], [300.0, 300.0, 0.0, -2.0]])
    for t in range(1, n + 1):
        steps = np.array([min(t, 15), t, t, t])[:, None]
        xy = starts[:, :2] + steps * starts[:, 2:] + rng.normal(0.0, 1.5, (4, 2))
        b = np.column_stack([xy, np.full(4, 40.0), np.full(4, 100.0)])
        keep = rng.random(4) > 0.15
        keep[0] = not 15 < t < 23
        scores = np.where(np.arange(4) == 0, 0.9, rng.uniform(0.3, 1.0, 4))
        yield FrameContext(t, detections=Detections(b[keep], scores[keep]))


def _tracks(graph):
    eng = Engine(graph, 0)
    out = []
    for frame in _crossing_stream():
        rec = eng.step(frame)
        out.append((eng.assignment.rows.tolist(), eng.assignment.cols.tolist(),
                    eng.assignment.rounds.tolist(),
                    np.asarray(rec.estimates["box"], float)))
    return out


def test_ocsort_and_bytetrack_rounds_are_their_named_pieces():
    """The rounds' shorthands are the built-in pieces: OC-SORT's rounds written with the
    momentum term and the IoU affinity against the last detection by name, and
    ByteTrack's with the IoU affinity by name, run exactly as the shorthands do."""
    from pgm.factors.association import IOU_AFFINITY, MOMENTUM
    from pgm.models import bytetrack, ocsort

    named = ({"iou": 0.3, "min_score": 0.6, "terms": [{"fn": MOMENTUM, "weight": 0.2}]},
             {"iou": 0.3, "min_score": 0.6,
              "affinity": {"fn": IOU_AFFINITY, "args": {"against": "last"}}})
    short = ocsort.build_graph(ocsort.Params(rounds=ocsort.rounds(0.6, 0.3)))
    explicit = ocsort.build_graph(ocsort.Params(rounds=named))
    f = explicit.factors_by_kind("association")[0]
    assert f.keeps_observations and f.plans[0].terms[0]["fn"] == MOMENTUM
    assert short.factors_by_kind("association")[0].plans[0].terms == f.plans[0].terms
    a, b = _tracks(short), _tracks(explicit)
    assert sum(len(r[0]) for r in a) > 50  # the stream is associated, in both rounds
    assert {k for r in a for k in r[2]} == {0, 1}
    for x, y in zip(a, b, strict=True):
        assert x[:3] == y[:3]
        np.testing.assert_array_equal(x[3], y[3])
    high = bytetrack.rounds(0.6, 0.1)
    by_name = [{**r, "affinity": {"fn": IOU_AFFINITY}} for r in high]
    a = _tracks(bytetrack.build_graph(bytetrack.Params()))
    b = _tracks(bytetrack.build_graph(bytetrack.Params(rounds=tuple(by_name))))
    assert [x[:3] for x in a] == [y[:3] for y in b]


def test_an_affinity_of_ones_own_matches_what_iou_cannot():
    """A round's own affinity replaces the IoU (its ``iou`` the least affinity of a match):
    a target that jumps past its box width loses its track under IoU and keeps it under a
    centre-distance affinity; the affinity is saved by name."""
    jump = [260.0, 50.0, 100.0, 200.0]  # 140 px past the prediction: IoU 0
    counts = {}
    own = {"iou": 0.1, "affinity": {"fn": centre_affinity, "args": {"scale": 1.0}}}
    for name, rounds in (("iou", [{"iou": 0.1}]), ("centre", [own])):
        eng = Engine(_with(sort.build_graph(sort.Params()), rounds=rounds), 0)
        _walk(eng)
        eng.step(_frame(9, jump))
        counts[name] = (len(eng.assignment.rows), eng.num_targets)
    assert counts["iou"] == (0, 2) and counts["centre"] == (1, 1)
    g = _with(sort.build_graph(sort.Params()), rounds=[own])
    saved = FactorGraph.from_dict(g.to_dict()).factors_by_kind("association")[0]
    assert saved.plans[0].affinity == {"fn": f"{__name__}:centre_affinity",
                                       "args": {"scale": 1.0}}
    with pytest.raises(ValueError, match="against, buffer or fuse_score"):
        DetectionAssociation("box", rounds=[{**own, "against": "last"}])
    with pytest.raises(ValueError, match="no weight"):
        DetectionAssociation("box", gates=[{"fn": mahalanobis_gate, "weight": 2.0}])
