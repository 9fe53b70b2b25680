"""The command line and the video runner: outputs, interruption, and every bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest
from cli_run import run_cli

from pgm.app.cli import main
from pgm.app.runner import track
from pgm.io.annotations import load_single_gt, load_tracks
from pgm.models import colour_pf
from pgm.synthetic import demo_scene


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """The demo scene (30 frames) as an OTB folder."""
    d = tmp_path_factory.mktemp("scene")
    demo_scene(seed=0, n_frames=30).write_otb(d)
    return d



def assert_one_line_error(code, err, *needles):
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("pgm: using")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], lines[0]


def test_track_writes_every_output(scene_dir, tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, _ = run_cli(capsys, "track", scene_dir, "--model", "colour-pf", "--gt",
                              scene_dir / "groundtruth_rect.txt", "--out", out,
                              "--particles", 50, "--seed", 3)
    assert code == 0
    assert "success AUC" in stdout
    rows = (out / "tracks.txt").read_text().splitlines()
    assert len(rows) == 30
    first = rows[0].split(",")
    assert first[0] == "1" and first[1] == "1" and first[7:] == ["-1", "-1", "-1"]
    gt = load_single_gt(scene_dir / "groundtruth_rect.txt")
    # frame 1 reports the initial box (1-based in the file, as the ground truth)
    np.testing.assert_allclose([float(v) for v in first[2:6]],
                               gt.boxes[0] + [1, 1, 0, 0], atol=1e-3)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["n_frames"] == 30 and 0.0 <= metrics["success_auc"] <= 1.0
    assert metrics["success_auc"] > 0.5  # the visible upper half keeps it on the person
    assert (out / "annotated.mp4").stat().st_size > 1000
    assert json.loads((out / "model.json").read_text())["format"] == "pgm-factor-graph"
    code, stdout, _ = run_cli(capsys, "eval", "--gt", scene_dir / "groundtruth_rect.txt",
                              "--pred", out / "tracks.txt", "--json")
    assert code == 0
    assert json.loads(stdout)["success_auc"] == pytest.approx(metrics["success_auc"])


def test_init_box_and_no_video(scene_dir, tmp_path, capsys):
    gt = load_single_gt(scene_dir / "groundtruth_rect.txt")
    x, y, w, h = gt.boxes[0]
    code, _, _ = run_cli(capsys, "track", scene_dir, "--init", f"{x + 1},{y + 1},{w},{h}",
                         "--out", tmp_path, "--no-video", "--max-frames", 5, "--quiet")
    assert code == 0
    assert not (tmp_path / "annotated.mp4").exists()
    assert not (tmp_path / "metrics.json").exists()
    assert len(load_tracks(tmp_path / "tracks.txt").frames) == 5


def test_interrupted_run_keeps_what_it_computed(scene_dir, tmp_path):
    gt = load_single_gt(scene_dir / "groundtruth_rect.txt")
    x, y, w, h = gt.boxes[0]
    graph = colour_pf.build_graph(colour_pf.Params(init_box=(x + w / 2, y + h / 2, w, h)))

    def frames():
        from pgm.io.video import open_source

        for k, item in enumerate(open_source(scene_dir).frames()):
            if k == 12:
                raise KeyboardInterrupt
            yield item

    with pytest.raises(KeyboardInterrupt):
        track(frames(), graph, rng=np.random.default_rng(0), out_dir=tmp_path,
              progress=False)
    assert len((tmp_path / "tracks.txt").read_text().splitlines()) == 12
    assert (tmp_path / "annotated.mp4").stat().st_size > 0


def test_ctrl_c_while_the_models_load_is_one_line(monkeypatch, capsys):
    """SIGINT before the run starts (parsing the command imports the models: a second on a
    cold start) ends as one line and 130, not a traceback."""
    import pgm.app.cli as cli

    def interrupted(argv):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "parse_args", interrupted)
    assert main(["track", "nowhere"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "pgm: interrupted by SIGINT before anything ran"


def test_debug_adds_the_traceback_and_keeps_the_exit_code(tmp_path, capsys):
    """``--debug`` prints the traceback before the same one-line message, and exits as
    without it (2 for bad input): the exception is not re-raised past ``main``, where the
    run's threads would still be alive at interpreter exit."""
    missing = tmp_path / "nowhere.mp4"
    assert main(["--debug", "track", str(missing), "--init", "1,1,5,5", "--out",
                 str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err
    assert err.strip().splitlines()[-1].startswith("pgm: error: ") and "nowhere.mp4" in err


def test_graph_command(tmp_path, capsys):
    for ext in ("png", "svg", "dot"):
        code, _, _ = run_cli(capsys, "graph", "colour-pf", "--out", tmp_path / f"g.{ext}")
        assert code == 0 and (tmp_path / f"g.{ext}").stat().st_size > 100
    code, _, err = run_cli(capsys, "graph", "colour-pf", "--out", tmp_path / "g.gif")
    assert_one_line_error(code, err, ".gif")


# -- bad input: one line, exit code 2, no traceback -------------------------------------
def test_missing_video(tmp_path, capsys):
    code, _, err = run_cli(capsys, "track", tmp_path / "nope.mp4", "--init", "1,1,5,5",
                           "--out", tmp_path / "o")
    assert_one_line_error(code, err, "nope.mp4")


def test_corrupt_video(tmp_path, capsys):
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8).tobytes())
    code, _, err = run_cli(capsys, "track", bad, "--init", "1,1,5,5", "--out", tmp_path / "o")
    assert_one_line_error(code, err, "bad.mp4")


def test_empty_folder(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    code, _, err = run_cli(capsys, "track", tmp_path / "empty", "--init", "1,1,5,5",
                           "--out", tmp_path / "o")
    assert_one_line_error(code, err, "empty")


def test_unreadable_frame(scene_dir, tmp_path, capsys):
    import shutil

    broken = tmp_path / "broken"
    shutil.copytree(scene_dir, broken)
    victim = sorted((broken / "img").iterdir())[4]
    victim.write_bytes(b"not a png at all")
    code, _, err = run_cli(capsys, "track", broken, "--out", tmp_path / "o", "--no-video",
                           "--quiet")
    assert_one_line_error(code, err, victim.name)
    # results before the bad frame are kept
    assert len((tmp_path / "o" / "tracks.txt").read_text().splitlines()) == 4


@pytest.mark.parametrize("box, needle", [("1000,1000,10,10", "outside"),
                                         ("-50,-50,10,10", "outside"),
                                         ("5,5,0,10", "zero or negative area"),
                                         ("5,5,10", "four"), ("a,b,c,d", "four"),
                                         ("5,nan,10,10", "finite")])
def test_bad_initial_box(scene_dir, tmp_path, capsys, box, needle):
    code, _, err = run_cli(capsys, "track", scene_dir, f"--init={box}", "--out", tmp_path)
    assert_one_line_error(code, err, needle)


def test_malformed_ground_truth(scene_dir, tmp_path, capsys):
    bad = tmp_path / "groundtruth_rect.txt"
    bad.write_text("10,10,5,5\nhello world\n")
    code, _, err = run_cli(capsys, "track", scene_dir, "--gt", bad, "--out", tmp_path / "o")
    assert_one_line_error(code, err, "groundtruth_rect.txt", "2")
    code, _, err = run_cli(capsys, "eval", "--gt", bad, "--pred", bad)
    assert_one_line_error(code, err, "groundtruth_rect.txt")


@pytest.mark.parametrize("count", ["0", "-3", "ten"])
def test_non_positive_particle_count(scene_dir, tmp_path, capsys, count):
    with pytest.raises(SystemExit) as exc:
        main(["track", str(scene_dir), "--particles", count, "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert_one_line_error(2, capsys.readouterr().err, "--particles")


def test_unknown_model(scene_dir, tmp_path, capsys):
    code, _, err = run_cli(capsys, "track", scene_dir, "--model", "kalman-magic",
                           "--out", tmp_path)
    assert_one_line_error(code, err, "unknown model 'kalman-magic'")
    code, _, err = run_cli(capsys, "graph", "kalman-magic", "--out", tmp_path / "g.png")
    assert_one_line_error(code, err, "kalman-magic")


def test_api_raises_value_error(scene_dir):
    graph = colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 10, 10)))
    with pytest.raises(ValueError, match="positive integer"):
        track(scene_dir, graph, rng=np.random.default_rng(0), num_particles=0, progress=False)
    with pytest.raises(ValueError, match="no such file or folder"):
        track(scene_dir / "missing", graph, rng=np.random.default_rng(0), progress=False)
    with pytest.raises(ValueError, match="positive width and height"):
        colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 0, 10)))
    with pytest.raises(ValueError, match="finite"):
        colour_pf.build_graph(colour_pf.Params(init_box=(50, np.nan, 5, 10)))


@pytest.mark.slow
def test_console_script_end_to_end(tmp_path):
    """The installed entry point: demo writes everything; a bad call is one line, exit 2."""
    res = subprocess.run([sys.executable, "-m", "pgm.app.cli", "demo", "--out", str(tmp_path),
                          "--frames", "20"], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    for name in ("tracks.txt", "annotated.mp4", "metrics.json", "graph.png", "graph.dot"):
        assert (tmp_path / name).stat().st_size > 0
        assert (tmp_path / "part-graph" / name).stat().st_size > 0
        assert (tmp_path / "single-object" / name).stat().st_size > 0
    assert "part graph (two nodes)" in res.stdout and "single-object" in res.stdout
    res = subprocess.run([sys.executable, "-m", "pgm.app.cli", "track", str(tmp_path / "nope"),
                          "--init", "1,1,2,2", "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_part_graph_track_and_graph(scene_dir, tmp_path, capsys):
    out = tmp_path / "pg"
    code, stdout, err = run_cli(capsys, "track", scene_dir, "--model", "part-graph", "--parts", 2,
                                "--out", out, "--show-particles", "--quiet")
    assert code == 0, err
    assert len((out / "tracks.txt").read_text().splitlines()) == 30
    assert json.loads((out / "metrics.json").read_text())["success_auc"] > 0.5
    model = json.loads((out / "model.json").read_text())
    assert [v["name"] for v in model["variables"]] == ["top", "bottom"]
    code, _, _ = run_cli(capsys, "graph", "part-graph", "--parts", 3, "--out", tmp_path / "g.dot")
    assert code == 0
    dot = (tmp_path / "g.dot").read_text()
    assert '"coupling:top-middle"' in dot and '"coupling:middle-bottom"' in dot
    code, _, err = run_cli(capsys, "track", scene_dir, "--model", "colour-pf", "--parts", 2,
                           "--out", tmp_path / "x")
    assert_one_line_error(code, err, "--parts does not apply")


@pytest.fixture(scope="module")
def mot_dir(tmp_path_factory):
    """A synthetic MOTChallenge sequence (40 frames) with detections."""
    from pgm.synthetic import multi_target_scene

    d = tmp_path_factory.mktemp("mot")
    multi_target_scene(seed=0, n_frames=40).write_mot(d, rng=0, sigma=1.0, clutter_rate=0.5)
    return d


@pytest.mark.parametrize("model", ["phd", "vb-phd"])
def test_multi_target_track_and_eval(mot_dir, tmp_path, capsys, model):
    out = tmp_path / model
    code, stdout, err = run_cli(capsys, "track", mot_dir, "--model", model, "--out", out,
                                "--show-particles")
    assert code == 0, err
    assert "MOTA" in stdout and "OSPA(50,1)" in stdout
    rows = [r.split(",") for r in (out / "tracks.txt").read_text().splitlines()]
    assert len({r[1] for r in rows}) >= 3  # several identities
    m = json.loads((out / "metrics.json").read_text())
    # measured (seed 0): phd MOTA 0.50, IDF1 0.71; vb-phd MOTA -0.19, IDF1 0.32 — its σ̂
    # grows to 12 px on this stiff-motion scene (see the issue-4 note); here the CLI
    # path is under test, the filters' accuracy is in test_phd_vb.py
    floor = {"phd": 0.3, "vb-phd": -0.5}[model]
    assert m["mota"] > floor and 0.0 < m["idf1"] <= 1.0, m
    # several targets: camera-motion compensation on where the camera moves
    assert json.loads((out / "run.json").read_text())["camera_motion"] == "auto"
    assert (out / "annotated.mp4").stat().st_size > 1000
    code, stdout, _ = run_cli(capsys, "eval", "--gt", mot_dir / "gt" / "gt.txt", "--pred",
                              out / "tracks.txt", "--json")
    assert code == 0
    assert json.loads(stdout)["mota"] == pytest.approx(m["mota"])


def test_multi_target_bad_input(mot_dir, scene_dir, tmp_path, capsys):
    code, _, err = run_cli(capsys, "track", mot_dir, "--model", "phd", "--detector", "yolo",
                           "--out", tmp_path)
    assert_one_line_error(code, err, "unknown detector 'yolo'")
    code, _, err = run_cli(capsys, "track", scene_dir, "--model", "phd", "--out", tmp_path)
    assert_one_line_error(code, err, "no public detections")
    code, _, err = run_cli(capsys, "track", mot_dir, "--model", "phd", "--init", "1,1,5,5",
                           "--out", tmp_path)
    assert_one_line_error(code, err, "--init does not apply")
    bad = tmp_path / "det.txt"
    bad.write_text("1,-1,10,10,5,5,0.9\n2,-1,oops\n")
    code, _, err = run_cli(capsys, "track", mot_dir, "--model", "phd", "--detections", bad,
                           "--out", tmp_path / "o")
    assert_one_line_error(code, err, "det.txt")
    code, _, err = run_cli(capsys, "track", scene_dir, "--model", "colour-pf", "--detector",
                           "mog2", "--out", tmp_path / "o2")
    assert_one_line_error(code, err, "--detections/--detector apply to")


def test_no_model_runs_the_best_single_object_configuration(scene_dir, tmp_path, capsys):
    gt = load_single_gt(scene_dir / "groundtruth_rect.txt")
    x, y, w, h = gt.boxes[0]
    code, _, err = run_cli(capsys, "track", scene_dir, "--init", f"{x + 1},{y + 1},{w},{h}",
                           "--out", tmp_path, "--no-video", "--max-frames", 5)
    assert code == 0 and "using model single-object" in err
    saved = json.loads((tmp_path / "model.json").read_text())
    kinds = sorted(f["type"] for f in saved["factors"] if f["kind"] == "likelihood")
    assert kinds == ["CorrelationFilterLikelihood"]
    assert set(saved["meta"]["confidence"]) == {"factor", "intercept", "slope", "spread_slope"}
    scores = np.loadtxt(tmp_path / "tracks.txt", delimiter=",")[:, 6]
    assert len(scores) == 5 and np.all((scores >= 0) & (scores <= 1))
    # one object: no camera-motion compensation unless asked for
    assert json.loads((tmp_path / "run.json").read_text())["camera_motion"] == "off"
    code, _, err = run_cli(capsys, "track", scene_dir, "--init", f"{x + 1},{y + 1},{w},{h}",
                           "--out", tmp_path / "auto", "--no-video", "--max-frames", 5,
                           "--camera-motion", "auto")
    assert code == 0, err
    assert json.loads((tmp_path / "auto" / "run.json").read_text())["camera_motion"] == "auto"


def test_multi_target_scores_flag_is_saved_in_the_model(mot_dir, tmp_path, capsys):
    def phd_params(out):
        model = json.loads((out / "model.json").read_text())
        text = json.dumps(model)
        assert "PHDLikelihood" in text
        facs = model["factors"] if isinstance(model.get("factors"), list) else \
            list(model["factors"].values())
        return next(f["params"] for f in facs if f["type"] == "PHDLikelihood")

    for choice in ("off", "mixture", "learned"):
        out = tmp_path / choice
        code, _, err = run_cli(capsys, "track", mot_dir, "--model", "phd", "--out", out,
                               "--quiet", "--no-video", "--scores", choice)
        assert code == 0, err
        p = phd_params(out)
        if choice == "off":
            assert "scores" not in p
        else:
            assert p["scores"]["model"] == choice
    with pytest.raises(SystemExit) as exc:
        main(["track", str(mot_dir), "--model", "phd", "--out", str(tmp_path / "x"),
              "--scores", "logistic"])
    assert exc.value.code == 2
    assert_one_line_error(2, capsys.readouterr().err, "--scores")


def test_a_saved_part_graph_reruns_on_a_folder_with_ground_truth(tmp_path, capsys):
    """Neither --init nor --gt: the sequence's own first box starts the saved model — the
    same run where it was saved, every part moved with the target's box on another."""
    seq = tmp_path / "scene"
    demo_scene(seed=1, n_frames=8).write_otb(seq)
    other = tmp_path / "other"
    demo_scene(seed=2, n_frames=8).write_otb(other)
    first, again, moved = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    common = ["--max-frames", "6", "--no-video", "--quiet"]
    assert run_cli(capsys, "track", seq, "--model", "part-graph", "--out", first, *common)[0] == 0
    code, _, err = run_cli(capsys, "track", seq, "--model", first / "model.json", "--out",
                           again, *common)
    assert code == 0, err
    assert (first / "tracks.txt").read_text() == (again / "tracks.txt").read_text()
    code, _, err = run_cli(capsys, "track", other, "--model", first / "model.json", "--out",
                           moved, "--init", "60,90,40,100", *common)
    assert code == 0, err
    saved = json.loads((moved / "model.json").read_text())
    priors = [f for f in saved["factors"] if f["kind"] == "prior"]
    assert len(priors) >= 2
    tops = [np.asarray(f["params"]["mean"])[:4] for f in priors]
    lo = min(m[1] - m[3] / 2 for m in tops)
    hi = max(m[1] + m[3] / 2 for m in tops)
    assert lo == pytest.approx(90 - 1, abs=1e-6) and hi == pytest.approx(90 - 1 + 100, abs=1e-6)


def test_noise_per_reaches_the_saved_kalman_noise(mot_dir, tmp_path, capsys):
    """``--noise-per``: at 10 frames/s (``--fps``; the default reads its noise as at 30)
    the saved transition's rate variances are 9 times the 30 frames/s ones per detection
    (the default) and 27 times with ``second``; a bad value is a one-line error."""
    def q(out):
        facs = json.loads((out / "model.json").read_text())["factors"]
        fac = next(f for f in (facs if isinstance(facs, list) else facs.values())
                   if f.get("name") == "transition:box")
        return np.diag(np.asarray(fac["params"]["Q"], dtype=float))

    qs = {}
    for name, extra in (("ref", ["--fps", "30"]), ("detection", ["--fps", "10"]),
                        ("second", ["--fps", "10", "--noise-per", "second"])):
        out = tmp_path / name
        code, _, err = run_cli(capsys, "track", mot_dir, "--model", "ocsort-colour",
                               "--no-video", "--quiet", "--max-frames", "3", "--out", out,
                               *extra)
        assert code == 0, err
        qs[name] = q(out)
    np.testing.assert_allclose(qs["detection"][4:] / qs["ref"][4:], 9.0)
    np.testing.assert_allclose(qs["second"][4:] / qs["ref"][4:], 27.0)
    np.testing.assert_allclose(qs["detection"][:4], qs["ref"][:4])
    bad = run_cli(capsys, "track", mot_dir, "--no-video", "--out", tmp_path / "bad",
                  "--noise-per", "minute")
    assert bad[0] != 0 and "--noise-per" in bad[2]


def test_filled_gaps_reach_the_track_file_and_the_metrics(mot_dir, tmp_path, capsys):
    """``--fill-gaps`` (and ``--fill-births``): the rows of a filled gap (and of a track's
    tentative frames) are written to tracks.txt when the track is found again (or
    confirmed), after the rows of that frame, the finished file is put in frame order, and
    it scores as metrics.json does; without them the file has fewer rows. The life cycle's
    options reach the saved model, and a bad value is a one-line error."""
    outs = {}
    for name, extra in (("none", ["--fill-gaps", "0", "--fill-births", "off"]),
                        ("fill", ["--fill-gaps", "0.5"]),
                        ("at-once", ["--recover-hits", "1", "--fill-after", "1",
                                     "--fill-births", "off"])):
        out = outs[name] = tmp_path / name  # the default fills 0.5 s: 0 must turn it off
        code, _, err = run_cli(capsys, "track", mot_dir, "--model", "ocsort-colour",
                               "--no-video", "--out", out, *extra)
        assert code == 0, err
        saved = json.loads((out / "model.json").read_text())["plates"][0]["lifecycle"]
        assert saved["fill_gaps"] == (0 if name == "none" else 15)  # 0.5 s at 30 frames/s
        # a lost track found again: reported after 3 matches in a row, its gap filled then
        # and a track's tentative frames reported when it is confirmed (off: not)
        assert (saved["recover_hits"], saved["fill_after"], saved["fill_births"]) == (
            (1, 1, False) if name == "at-once" else (3, None, name == "fill"))
    bad = run_cli(capsys, "track", mot_dir, "--no-video", "--out", tmp_path / "bad",
                  "--fill-after", "0")
    assert bad[0] != 0 and "--fill-after" in bad[2]
    bad = run_cli(capsys, "track", mot_dir, "--no-video", "--out", tmp_path / "bad",
                  "--fill-births", "maybe")
    assert bad[0] != 0 and "--fill-births" in bad[2]
    rows = {k: np.loadtxt(o / "tracks.txt", delimiter=",") for k, o in outs.items()}
    assert np.all(np.diff(rows["none"][:, 0]) >= 0)
    assert len(rows["fill"]) > len(rows["none"])
    assert np.all(np.diff(rows["fill"][:, 0]) >= 0)  # the late rows sorted in at the end
    for out in outs.values():
        m = json.loads((out / "metrics.json").read_text())
        code, stdout, _ = run_cli(capsys, "eval", "--gt", mot_dir / "gt" / "gt.txt", "--pred",
                                  out / "tracks.txt", "--json")
        assert code == 0 and json.loads(stdout)["mota"] == pytest.approx(m["mota"])


def test_the_sort_familys_scores_flag_reaches_the_saved_association(mot_dir, tmp_path,
                                                                     capsys):
    """``--scores`` for the multi-target default: each learned map is what the saved
    association reads (the default's own, ``placed-over``, without the flag), and an
    unknown map is a one-line error."""
    def score_map(out):
        model = json.loads((out / "model.json").read_text())
        facs = model["factors"] if isinstance(model.get("factors"), list) else \
            list(model["factors"].values())
        return next(f["params"]["score_map"] for f in facs
                    if f["type"] == "DetectionAssociation")

    for choice in (None, "quantile", "quantile-gated", "quantile-rebased", "placed",
                   "placed-rebased", "learned"):
        out = tmp_path / str(choice)
        flag = [] if choice is None else ["--scores", choice]
        code, _, err = run_cli(capsys, "track", mot_dir, "--out", out, "--quiet",
                               "--no-video", *flag)
        assert code == 0, err
        assert score_map(out) == (choice or "placed-over")
    with pytest.raises(SystemExit) as exc:
        main(["track", str(mot_dir), "--out", str(tmp_path / "x"), "--scores", "quantiles"])
    assert exc.value.code == 2
    assert_one_line_error(2, capsys.readouterr().err, "--scores")
