"""The single-object model's per-frame noise converted from the rate it was chosen at
(``single_object.REFERENCE_FPS``) to a video's declared rate: ``frame_step = τ``
multiplies the position, scale and angle noise by ``√τ`` (a random walk's step over τ
reference frames) — checked against the random walk's variance after one second; the
rate reaches the model only where the video declares it (or ``pgm track --fps``)."""

import json
from pathlib import Path

import numpy as np
import pytest

from pgm.models import part_graph, single_object
from pgm.models.config import VideoInfo, default_build


def _transition(graph):
    return next(f for f in graph.factors.values() if f.kind == "transition")


def test_frame_step_scales_the_noise_by_its_square_root():
    box = (100.0, 80.0, 40.0, 60.0)
    base = _transition(part_graph.build_graph(part_graph.Params(
        init_box=box, n_parts=1, scale_noise=0.005, rotation_noise=0.01, appearance="cf",
        num_particles=10)))
    slow = _transition(part_graph.build_graph(part_graph.Params(
        init_box=box, n_parts=1, scale_noise=0.005, rotation_noise=0.01, appearance="cf",
        num_particles=10, frame_step=3.0)))
    np.testing.assert_allclose(slow.params()["noise_std"],
                               np.sqrt(3.0) * np.asarray(base.params()["noise_std"]))
    assert slow.params()["scale_noise"] == pytest.approx(np.sqrt(3.0) * 0.005)
    at10 = _transition(single_object.build_graph(single_object.Params(init_box=box, fps=10.0)))
    at30 = _transition(single_object.build_graph(single_object.Params(init_box=box, fps=30.0)))
    plain = _transition(single_object.build_graph(single_object.Params(init_box=box)))
    assert json.dumps(at30.to_dict(), default=list) == json.dumps(plain.to_dict(), default=list)
    np.testing.assert_allclose(at10.params()["noise_std"],
                               np.sqrt(3.0) * np.asarray(plain.params()["noise_std"]))
    with pytest.raises(ValueError, match="fps"):
        single_object.build_graph(single_object.Params(init_box=box, fps=float("nan")))


def test_one_second_of_random_walk_is_the_same_at_any_rate():
    """Oracle: with no damping and no jumps the transition is a random walk; after one
    second its variance is 30 s² at 30 frames/s and 10 (√3 s)² at 10: the same. Checked
    on 20000 particles (the variance's relative standard error is √(2/n) = 1 %)."""
    box = (100.0, 80.0, 40.0, 60.0)
    rng = np.random.default_rng(0)
    spread = {}
    for fps in (30.0, 10.0):
        tr = _transition(single_object.build_graph(single_object.Params(
            init_box=box, fps=fps, damping=0.0, jump_prob=0.0, scale_noise=0.0)))
        x = np.tile(np.asarray(box), (20000, 1))
        for _ in range(int(fps)):
            x = tr.sample(rng, x, x)
        spread[fps] = x[:, :2].var(axis=0)
    s = 0.03 * np.sqrt(40.0 * 60.0)
    for fps in spread:
        np.testing.assert_allclose(spread[fps], 30 * s**2, rtol=0.05)  # 5 standard errors


def test_the_rate_reaches_the_model_only_where_the_video_declares_it(tmp_path: Path, capsys):
    from cli_run import run_cli

    from pgm.io.video import open_source
    from pgm.synthetic import demo_scene

    seq = demo_scene(seed=0, n_frames=12)
    otb = seq.write_otb(tmp_path / "otb")
    src = open_source(otb)
    assert not src.fps_declared and src.fps == 25.0
    src.declare_fps(10)
    assert src.fps_declared and src.fps == 10.0
    mot = seq.write_mot(tmp_path / "mot")
    assert open_source(mot).fps_declared and open_source(mot).fps == 30.0
    cfg = single_object.CONFIG
    undeclared = default_build(cfg, {}, VideoInfo(fps=25.0, fps_declared=False,
                                                  init_box=(35.0, 140.0, 30.0, 80.0)))
    declared = default_build(cfg, {}, VideoInfo(fps=10.0, init_box=(35.0, 140.0, 30.0, 80.0)))
    assert VideoInfo().fps == 25.0 and not VideoInfo().fps_declared  # nothing given
    assert VideoInfo(fps=10.0).fps_declared
    drawn = cfg.graph_for(video=VideoInfo(init_box=(35.0, 140.0, 30.0, 80.0)))
    np.testing.assert_array_equal(_transition(drawn).params()["noise_std"],
                                  _transition(undeclared).params()["noise_std"])
    ratio = (np.asarray(_transition(declared).params()["noise_std"][:2])
             / np.asarray(_transition(undeclared).params()["noise_std"][:2]))
    np.testing.assert_allclose(ratio, np.sqrt(3.0))
    noise = {}
    for extra in ((), ("--fps", "10")):
        out = tmp_path / ("run" + "".join(extra))
        code, _, err = run_cli(capsys, "track", otb, "--out", out, "--no-video", "--quiet",
                               "--max-frames", "3", *extra)
        assert code == 0, err
        saved = json.loads((out / "model.json").read_text())
        noise[extra] = next(f["params"]["noise_std"][0] for f in saved["factors"]
                            if f["kind"] == "transition")
    assert noise[("--fps", "10")] == pytest.approx(np.sqrt(3.0) * noise[()])
    code, _, err = run_cli(capsys, "track", otb, "--out", tmp_path / "bad", "--fps", "0")
    assert code != 0 and "frame rate" in err
    # a folder that does not say its rate gets a note naming --fps; not once it is given
    notes = {}
    for extra in ((), ("--fps", "10")):
        code, _, err = run_cli(capsys, "track", otb, "--out", tmp_path / ("note" + "".join(extra)),
                               "--no-video", "--max-frames", "2", *extra)
        assert code == 0, err
        notes[extra] = "does not say its own" in err and "--fps F" in err
    assert notes == {(): True, ("--fps", "10"): False}


def test_redetection_chances_are_per_second():
    """Re-detection's re-appearance chance and its scan's false-alarm rate are read per
    frame at the reference rate and given to a video's frames as ``1 − (1 − p)^τ``: the
    same chance over a second (oracle: one second at 10 frames/s against three frames at
    30 of the same chance); at the reference rate they are the values given, exactly."""
    box, size = (100.0, 80.0, 40.0, 60.0), (320, 240)

    def chances(fps):
        g = single_object.build_graph(single_object.Params(init_box=box, frame_size=size,
                                                           fps=fps))
        proposal = next(f for f in g.factors.values()
                        if type(f).__name__ == "RedetectionProposal")
        return _transition(g).reappear_prob, proposal.false_alarm

    ref = part_graph.RedetectionAndAngle()
    assert chances(None) == chances(30.0) == (ref.reappear_prob, ref.redetect_false_alarm)
    for fps in (10.0, 7.0):
        tau = 30.0 / fps
        for got, p in zip(chances(fps), (ref.reappear_prob, ref.redetect_false_alarm),
                          strict=True):
            # the chance of no event over a second is the same at both rates
            assert (1 - got) ** fps == pytest.approx((1 - p) ** 30.0, rel=1e-12)
            assert got == pytest.approx(1 - (1 - p) ** tau, rel=1e-12)
