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
