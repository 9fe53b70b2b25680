"""The scale-aware PHD: state and noise in units of each target's own height."""

import numpy as np

from pgm import FrameContext
from pgm.inference import Engine
from pgm.models import phd, vb_phd


def _walk(n=60, rng=None):
    """One person walking towards the camera: height 60 -> 120 px, foot point moving."""
    rng = np.random.default_rng(0) if rng is None else rng
    h = 60.0 * 2.0 ** (np.arange(n) / (n - 1))
    foot = np.column_stack([200 + 1.5 * np.arange(n), 150 + h])
    z = np.column_stack([foot + 0.08 * h[:, None] * rng.standard_normal((n, 2)),
                         np.log(h) + 0.05 * rng.standard_normal(n)])
    return h, foot, z


def _run(module, z):
    params = phd.video_params(module.Params, 640, 480, 25.0, scale_aware=True)
    eng = Engine(module.build_graph(params), np.random.default_rng(1))
    return [eng.step(FrameContext(t + 1, measurements=z[t:t + 1])).estimates["targets"]
            for t in range(len(z))]


def test_scale_aware_phd_keeps_a_target_whose_height_doubles():
    h, foot, z = _walk()
    for module in (phd, vb_phd):
        est = _run(module, z)
        ids = {int(i) for e in est[5:] for i in e["ids"]}
        assert len(ids) == 1, (module.__name__, ids)  # one identity throughout
        last = est[-1]["states"][0]
        assert abs(np.exp(last[4]) / h[-1] - 1) < 0.1  # the state's height followed
        assert np.linalg.norm(last[[0, 2]] - foot[-1]) < 0.15 * h[-1]


def test_scale_aware_graph_round_trips_and_plain_default_is_unchanged(tmp_path):
    g = vb_phd.build_graph(phd.video_params(vb_phd.Params, 640, 480, 25.0, scale_aware=True))
    g.save(tmp_path / "m.json")
    from pgm import FactorGraph

    assert FactorGraph.load(tmp_path / "m.json") == g
    assert g.variables["targets"].dim == 6 and g.variables["noise"].dim == 3
    assert phd.build_graph(phd.Params()).variables["targets"].dim == 4


def test_extraction_merges_one_persons_duplicate_boxes_by_foot_point():
    """DPM's second box on a person is √2 taller (3.5 σ in log h at σ 0.1) at almost the
    same foot point: one estimate. Two people side by side at the same height, half a
    height apart: two estimates."""
    from pgm.inference.phd import extract

    h = 100.0
    z = np.array([[300.0, 400.0, np.log(h)],            # a person
                  [301.0, 402.0, np.log(h * 2 ** 0.5)],  # the detector's taller duplicate
                  [350.0, 400.0, np.log(h)]])            # a second person, 0.5 h away
    x = np.zeros((3, 6))
    x[:, [0, 2, 4]] = z  # one particle per detection, fully associated
    res = {"W": np.ones(3), "omega": np.eye(3), "x": x, "z": z}
    sigma = np.array([0.08, 0.08, 0.1])
    states, idx = extract(res, 3.0, sigma, log_h_row=2, scaled=np.array([True, True, False]))
    assert sorted(idx.tolist()) == [0, 2]
    # the same three as plain foot points in pixels (σ 8 px): the same answer
    states, idx = extract({**res, "z": z[:, :2], "x": x[:, :4]}, 3.0, np.array([8.0, 8.0]))
    assert sorted(idx.tolist()) == [0, 2]
