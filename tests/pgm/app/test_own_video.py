"""Issue 37: a user's own video — the last bad inputs of the sweep (item 7), run
reproducibility and the API a user imports (item 6)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_run import run_cli

from pgm.core.graph import FactorGraph
from pgm.io.annotations import InputError, load_mot
from pgm.observation.hog import hog_available
from pgm.synthetic import multi_target_scene

N_FRAMES = 6


@pytest.fixture(scope="module")
def mot(tmp_path_factory):
    """A small MOT folder (detections and ground truth)."""
    d = tmp_path_factory.mktemp("own") / "mot"
    multi_target_scene(seed=0, n_frames=N_FRAMES).write_mot(d, rng=0, sigma=1.0,
                                                            clutter_rate=0.5)
    return d


@pytest.fixture(scope="module")
def mot_video(tmp_path_factory):
    """The MOT folder's frames as a video beside its ``seqinfo.ini``, ``det/`` and ``gt/``
    (as PETS09-S2L1-video is), the image folder removed."""
    import shutil

    import cv2

    d = tmp_path_factory.mktemp("ownvideo") / "seq"
    scene = multi_target_scene(seed=0, n_frames=N_FRAMES, n_objects=3)
    scene.write_mot(d, rng=0, sigma=1.0, clutter_rate=0.5)
    shutil.rmtree(d / "img1")
    h, w = scene.frames[0].shape[:2]
    writer = cv2.VideoWriter(str(d / "clip.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, (w, h))
    for img in scene.frames:
        writer.write(img)
    writer.release()
    return d / "clip.avi"


# -- item 1: a video with no options -------------------------------------------------------
def test_a_video_with_detections_beside_it_tracks_everyone(mot_video, tmp_path, capsys):
    code, _, err = run_cli(capsys, "track", mot_video, "--out", tmp_path / "run", "--no-video")
    assert code == 0, err
    assert "no --model given; the source has detections: " in err
    assert "det.txt" in err
    info = json.loads((tmp_path / "run" / "run.json").read_text())
    from pgm.models import DEFAULT_MULTI_TARGET
    assert info["model"] == DEFAULT_MULTI_TARGET
    assert (tmp_path / "run" / "metrics.json").is_file()  # scored on gt/gt.txt beside it


def test_one_object_on_a_ground_truth_of_several_people(mot_video, tmp_path, capsys):
    """Without --init the run is refused naming the choices; --gt-id picks a person;
    --init alone runs unscored."""
    from pgm.io.annotations import load_mot, load_single_gt
    gt_file = mot_video.parent / "gt" / "gt.txt"
    gt = load_mot(gt_file, kind="gt")
    people, first = np.unique(gt.ids), np.unique(gt.ids[gt.frames == 1])
    assert people.size >= 2 and first.size >= 1
    base = ["track", mot_video, "--model", "single-object", "--no-video"]
    code, _, err = run_cli(capsys, *base, "--out", tmp_path / "a")
    assert code == 2 and err.count("pgm: error:") == 1
    listed = ", ".join(map(str, first))
    for needle in (f"holds {people.size} people", f"--gt-id ID (annotated in frame 1: {listed})",
                   "--init", "--detections FILE or --detector NAME"):
        assert needle in err, (needle, err)
    pick = int(first[-1])
    code, _, err = run_cli(capsys, *base, "--out", tmp_path / "b", "--gt-id", pick)
    assert code == 0, err
    two = load_single_gt(gt_file, "mot", obj_id=pick)
    m = json.loads((tmp_path / "b" / "metrics.json").read_text())
    assert m["n_frames"] == len(two.frames) and m["success_auc"] > 0.5
    init = ",".join(str(v + (1 if k < 2 else 0)) for k, v in enumerate(two.boxes[0]))
    code, _, err = run_cli(capsys, *base, "--out", tmp_path / "c", "--init", init)
    assert code == 0, err  # --init: the sequence's own ground truth is not read
    assert not (tmp_path / "c" / "metrics.json").exists()
    code, _, err = run_cli(capsys, *base, "--out", tmp_path / "d", "--init", init,
                           "--gt", gt_file)
    assert code == 0, err
    assert f"holds {people.size} people; the run is not scored" in err
    assert not (tmp_path / "d" / "metrics.json").exists()


@pytest.mark.parametrize("extra, needle", [
    (["--gt-id", "9"], "--gt-id 9: no such identity"),
    (["--gt-id", "1", "--model", "sort"], "tracks every target"),
])
def test_a_wrong_gt_id_is_one_line(mot_video, tmp_path, capsys, extra, needle):
    argv = ["track", mot_video, "--no-video", "--out", tmp_path / "r", *extra]
    if "--model" not in extra:
        argv += ["--model", "single-object"]
    code, _, err = run_cli(capsys, argv)
    lines = [ln for ln in err.splitlines() if ln.startswith("pgm: error:")]
    assert code == 2 and len(lines) == 1 and needle in lines[0], err


def test_gt_id_on_a_single_object_ground_truth_is_refused(tmp_path, capsys):
    from pgm.synthetic import demo_scene

    seq = demo_scene(seed=0, n_frames=4).write_otb(tmp_path / "walker")
    code, _, err = run_cli(capsys, "track", seq, "--gt-id", 1, "--out", tmp_path / "r",
                           "--no-video")
    assert code == 2 and "--gt-id applies to a MOTChallenge ground truth" in err, err


# -- item 7: the last bad inputs ---------------------------------------------------------
@pytest.mark.parametrize("ident", [2 ** 63 - 1, -2 ** 63, 2 ** 53 + 1, 5, -1])
def test_any_64_bit_integer_is_an_id(tmp_path, ident):
    """Ids are read exactly, also where a float would round them (2^53 + 1)."""
    p = tmp_path / "det.txt"
    p.write_text(f"1,{ident},10,10,20,30,0.9\n2,7,12,10,20,30,0.8\n")
    table = load_mot(p, kind="det")
    assert table.ids.dtype == np.int64 and table.ids.tolist() == [ident, 7]


@pytest.mark.parametrize("ident", [str(2 ** 63), "1e19", "3.5", "nan"])
def test_an_id_that_is_not_a_64_bit_integer_is_refused_naming_its_line(tmp_path, ident):
    p = tmp_path / "det.txt"
    p.write_text(f"1,7,10,10,20,30,0.9\n2,{ident},12,10,20,30,0.8\n")
    with pytest.raises(InputError, match=r"det\.txt:2: id must be"):
        load_mot(p, kind="det")


def test_a_detection_id_of_2_63_minus_1_tracks(mot, tmp_path, capsys):
    """The CLI runs on a detection file whose ids are the largest 64-bit integer."""
    det = mot / "det" / "det.txt"
    rows = [line.split(",") for line in det.read_text().splitlines()]
    det_big = tmp_path / "det_big.txt"
    det_big.write_text("".join(",".join([r[0], str(2 ** 63 - 1), *r[2:]]) + "\n"
                               for r in rows))
    code, _, err = run_cli(capsys, "track", mot, "--model", "sort", "--detections", det_big,
                           "--out", tmp_path / "run", "--no-video", "--quiet")
    assert code == 0, err
    assert (tmp_path / "run" / "tracks.txt").read_text().strip()


def _declaration():
    from pgm.models import single_object
    return single_object.build_graph(single_object.Params(init_box=(50, 50, 20, 20))).to_dict()


@pytest.mark.parametrize("key, value, needle", [
    ("variables", "x", "'variables' must be a list"),
    ("variables", ["x"], "malformed variable declaration 'x'"),
    ("variables", [1], "malformed variable declaration 1"),
    ("factors", "x", "'factors' must be a list"),
    ("plates", "x", "'plates' must be a list"),
    ("meta", "x", "'meta' must be an object"),
])
def test_a_malformed_declaration_is_a_value_error(key, value, needle):
    d = _declaration() | {key: value}
    with pytest.raises(ValueError, match=needle):
        FactorGraph.from_dict(d)
    d = _declaration()
    del d["variables"]
    with pytest.raises(ValueError, match="'variables' must be a list"):
        FactorGraph.from_dict(d)
    assert FactorGraph.from_dict(_declaration() | {"plates": None}) is not None


def test_a_malformed_model_file_is_one_line_from_the_cli(mot, tmp_path, capsys):
    model = tmp_path / "model.json"
    model.write_text(json.dumps(_declaration() | {"variables": "x"}))
    code, _, err = run_cli(capsys, "graph", model, "--out", tmp_path / "g.dot")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "'variables' must be a list" in lines[0], err


# -- item 6: reproducibility and the API ---------------------------------------------------
def test_run_json_records_seed_command_version_and_commit(mot, tmp_path, capsys):
    import pgm

    out = tmp_path / "run"
    argv = ["track", str(mot), "--model", "sort", "--out", str(out), "--seed", "7",
            "--no-video", "--quiet"]
    code, stdout, err = run_cli(capsys, argv)
    assert code == 0, err
    assert stdout == "" and err == ""  # --quiet: nothing but errors
    info = json.loads((out / "run.json").read_text())
    assert info["seed"] == 7 and info["command"] == ["pgm", *argv]
    assert info["pgm_version"] == pgm.__version__
    commit = info["commit"]
    assert commit is None or (len(commit.split("+")[0]) == 40
                              and commit.split("+")[1:] in ([], ["dirty"]))


def test_the_api_records_the_seed_it_was_given(tmp_path):
    from pgm.app.runner import track
    from pgm.models import colour_pf
    from pgm.synthetic import demo_scene

    seq = demo_scene(seed=0, n_frames=4).write_otb(tmp_path / "walker")
    from pgm.io.annotations import load_single_gt
    x, y, w, h = load_single_gt(seq / "groundtruth_rect.txt").boxes[0]
    graph = colour_pf.build_graph(colour_pf.Params(init_box=(x + w / 2, y + h / 2, w, h),
                                                   num_particles=20))
    for rng, seed in ((3, 3), (np.random.default_rng(3), None)):
        track(seq, graph, rng=rng, out_dir=tmp_path / "o", write_video=False, progress=False)
        info = json.loads((tmp_path / "o" / "run.json").read_text())
        assert info["seed"] == seed and info["command"] is None


def test_import_pgm_gives_the_subpackages_on_first_use():
    """``import pgm`` leaves them unimported (``--help`` stays fast); the attribute
    imports them."""
    code = ("import sys, pgm; before = 'pgm.models' in sys.modules; "
            "e = pgm.inference.Engine; m = pgm.models.single_object; "
            "print(before, 'pgm.models' in sys.modules, sorted(set(pgm.SUBPACKAGES) - "
            "set(dir(pgm))))")
    import subprocess
    import sys
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "True", "[]"]
    import pgm
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        pgm.nope  # noqa: B018


def test_report_does_not_average_repeats_of_one_seed(mot, tmp_path, capsys):
    """Two runs with the same seed and settings repeat one run: not seeds of it."""
    from pgm.app.report import find_runs, group_runs, load_run

    root = tmp_path / "exp"
    for folder, seed in (("a", 0), ("b", 0), ("c", 1)):
        code, _, err = run_cli(capsys, "track", mot, "--model", "sort", "--out",
                               root / "seq" / "sort" / folder, "--seed", seed, "--no-video",
                               "--quiet")
        assert code == 0, err
    groups = group_runs(load_run(f, root) for f in find_runs(root))
    labels = sorted((g.label, len(g.runs)) for g in groups)
    assert labels == [("sort", 1), ("sort (seed 0, repeat 1)", 1),
                      ("sort (seed 0, repeat 2)", 1)]
    for folder in ("a", "b"):  # a run without a recorded seed is taken as a seed
        info = json.loads((root / "seq" / "sort" / folder / "run.json").read_text())
        del info["seed"]
        (root / "seq" / "sort" / folder / "run.json").write_text(json.dumps(info))
    groups = group_runs(load_run(f, root) for f in find_runs(root))
    assert [(g.label, len(g.runs)) for g in groups] == [("sort", 3)]


# -- item 3: the SORT family's standard settings ----------------------------------------------
@pytest.mark.parametrize("model", ["sort", "bytetrack", "ocsort", "botsort", "ocsort-colour"])
def test_the_standard_settings_are_options_of_each_core(model, capsys):
    code, out, _ = run_cli(capsys, "track", "--model", model, "--help")
    assert code == 0
    for flag in ("--lost-track-buffer", "--min-hits", "--iou-threshold"):
        assert flag in out, (model, flag)


def test_the_standard_settings_reach_the_tracker(mot, tmp_path, capsys):
    from pgm.io.video import open_source
    from pgm.models.sort import lost_frames

    out = tmp_path / "run"
    code, _, err = run_cli(capsys, "track", mot, "--model", "bytetrack", "--min-hits", 4,
                           "--lost-track-buffer", 12, "--iou-threshold", 0.45, "--out", out,
                           "--no-video", "--quiet")
    assert code == 0, err
    model = json.loads((out / "model.json").read_text())
    life = model["plates"][0]["lifecycle"]
    fps = open_source(mot).fps
    assert life["confirm_hits"] == 4 and life["max_lost"] == lost_frames(12, fps)
    rounds = [f["params"]["rounds"] for f in model["factors"] if "rounds" in f["params"]][0]
    assert len(rounds) == 2 and all(r["iou"] == 0.45 for r in rounds)


@pytest.mark.parametrize("argv, needle", [
    (["--model", "sort", "--iou-threshold", "1.5"], "--iou-threshold must be in [0, 1]"),
    (["--model", "sort", "--min-hits", "0"], "argument --min-hits: invalid integer value: '0'"),
    (["--model", "single-object", "--min-hits", "3"],
     "--min-hits does not apply to model 'single-object' (models that take it: "),
])
def test_a_misplaced_or_bad_setting_is_one_line(mot, tmp_path, capsys, argv, needle):
    code, _, err = run_cli(capsys, "track", mot, *argv, "--out", tmp_path / "r", "--no-video")
    lines = [ln for ln in err.splitlines() if ln.startswith("pgm: error:")]
    assert code == 2 and len(lines) == 1 and needle in lines[0], err


# -- item 2: a detector of one's own -----------------------------------------------------------
DETECTOR_FILE = '''
import numpy as np

def detect(image):
    """Boxes where the frame is saturated (the synthetic people wear colours)."""
    import cv2
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    n, _, stats, _ = cv2.connectedComponentsWithStats((hsv[:, :, 1] > 80).astype(np.uint8))
    boxes = stats[1:, :4].astype(float)
    keep = boxes[:, 3] >= 20
    return boxes[keep], stats[1:, 4][keep] / (boxes[keep, 2] * boxes[keep, 3])

def broken(image):
    raise RuntimeError("out of GPU memory")

def flat(image):
    return np.array([[10.0, 10.0, 0.0, 20.0, 0.9]])

NOT_A_FUNCTION = 3
'''


@pytest.fixture(scope="module")
def det_file(tmp_path_factory):
    """The detectors' file, written once (a module is imported once per process)."""
    path = tmp_path_factory.mktemp("dets") / "own_detectors.py"
    path.write_text(DETECTOR_FILE)
    return path


def test_callable_detector_reads_every_return_form():
    from pgm.observation.detections import CallableDetector, Detections

    img = np.zeros((50, 60, 3), np.uint8)
    boxes, scores = np.array([[1.0, 2, 10, 20], [5, 6, 7, 8]]), np.array([0.9, 0.2])
    for fn in (lambda im: (boxes, scores), lambda im: np.c_[boxes, scores],
               lambda im: Detections(boxes, scores)):
        d = CallableDetector(fn)(3, img)
        assert d.boxes.tolist() == boxes.tolist() and d.scores.tolist() == scores.tolist()
    assert len(CallableDetector(lambda im: np.zeros((0, 5)))(1, img)) == 0
    assert len(CallableDetector(lambda im: ([], []))(1, img)) == 0


@pytest.mark.parametrize("fn, needle", [
    (lambda im: (np.array([[1.0, 2, 0, 20]]), np.array([0.5])), "detection 0 is"),
    (lambda im: (np.array([[1.0, 2, 3, 20]]), np.array([np.nan])), "detection 0 is"),
    (lambda im: (np.ones((2, 4)), np.ones(3)), "2 boxes but 3 scores"),
    (lambda im: np.ones((2, 3)), "expected Detections"),
    (lambda im: 1 / 0, "ZeroDivisionError"),
])
def test_a_bad_detection_names_the_detector_and_the_frame(fn, needle):
    from pgm.observation.detections import CallableDetector

    with pytest.raises(InputError, match=r"detector 'mine', frame 7: .*") as err:
        CallableDetector(fn, name="mine")(7, np.zeros((10, 10, 3), np.uint8))
    assert needle in str(err.value)


def test_your_own_detector_from_the_command_line(mot, det_file, tmp_path, capsys, monkeypatch):
    code, _, err = run_cli(capsys, "track", mot, "--detector", f"{det_file}:detect",
                           "--out", tmp_path / "a", "--no-video")
    assert code == 0, err
    m = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert m["mota"] > 0.3  # it finds the people
    monkeypatch.syspath_prepend(str(det_file.parent))  # a module on the path, by name
    code, _, err = run_cli(capsys, "track", mot, "--detector", "own_detectors:detect", "--out",
                           tmp_path / "b", "--no-video", "--quiet")
    assert code == 0, err
    assert (tmp_path / "a" / "tracks.txt").read_text() == (tmp_path / "b" / "tracks.txt").read_text()


@pytest.mark.parametrize("function, needle", [
    ("broken", "frame 1: RuntimeError: out of GPU memory"),
    ("flat", "detection 0 is [10.0, 10.0, 0.0, 20.0]"),
    ("nope", "has no function 'nope'"),
    ("NOT_A_FUNCTION", "has no function 'NOT_A_FUNCTION'"),
])
def test_a_broken_detector_is_one_line(mot, det_file, tmp_path, capsys, function, needle):
    code, _, err = run_cli(capsys, "track", mot, "--detector", f"{det_file}:{function}",
                           "--out", tmp_path / "r", "--no-video")
    lines = [ln for ln in err.splitlines() if ln.startswith("pgm: error:")]
    assert code == 2 and len(lines) == 1 and needle in lines[0], err
    assert "Traceback" not in err


# -- item 5: the overlay --------------------------------------------------------------------
def test_the_legend_is_drawn_at_the_bottom_left():
    from pgm.plotting.annotate import annotate

    img = np.full((240, 320, 3), 120, np.uint8)
    plain = annotate(img, boxes=[[200, 20, 40, 80]], ids=[3])
    with_legend = annotate(img, boxes=[[200, 20, 40, 80]], ids=[3], gt_boxes=[[10, 10, 30, 60]],
                           ignore_boxes=[[100, 100, 40, 40]], legend=True)
    corner = (slice(150, 240), slice(0, 200))
    assert np.array_equal(plain[corner], img[corner])  # nothing there without the legend
    drawn = with_legend[corner]
    assert (drawn == int(120 * 0.35)).all(axis=2).mean() > 0.3  # its see-through plate
    assert (drawn > 200).all(axis=2).sum() > 50  # its white words and the ground truth line
    # the ignored region is dashed grey: some of its outline drawn, some left out
    top = with_legend[100, 100:141]
    grey = np.all(np.abs(top.astype(int) - 150) <= 40, axis=1) & ~np.all(top == 120, axis=1)
    assert 0.2 < grey.mean() < 0.9


def test_labels_of_boxes_on_one_corner_do_not_collide():
    from pgm.plotting.annotate import _draw_box

    img = np.zeros((200, 200, 3), np.uint8)
    taken: list = []
    for i in (1, 2, 3):
        _draw_box(img, (50, 50, 60, 90), (255, 255, 255), 2, 1.0, str(i) * 2, taken)
    for a in range(3):
        for b in range(a + 1, 3):
            p, q = taken[a], taken[b]
            assert p[2] <= q[0] or q[2] <= p[0] or p[3] <= q[1] or q[3] <= p[1], (p, q)


def test_trails_keep_the_last_n_centres_of_each_identity():
    from pgm.app.overlay import Trails

    assert Trails(0).update([1], [[0, 0, 10, 10]]) is None
    t = Trails(3)
    for k in range(5):
        out = t.update([1] if k != 2 else [1, 7], [[k, 0, 10, 10]] if k != 2
                       else [[k, 0, 10, 10], [50, 50, 4, 4]])
    assert out[1].tolist() == [[7.0, 5.0], [8.0, 5.0], [9.0, 5.0]]
    assert out[7].tolist() == [[52.0, 52.0]]  # seen at frame 3, within the last three
    out = t.update([1], [[5, 0, 10, 10]])
    assert 7 not in out and len(out[1]) == 3  # three frames on, forgotten
    with pytest.raises(ValueError, match="trails"):
        Trails(-1)


def test_the_header_is_plain_words(tmp_path):
    """No particle details in the header unless asked for (``--show-particles``)."""
    from pgm.app.overlay import annotated_frame, frame_caption
    from pgm.inference import Engine
    from pgm.models import single_object
    from pgm.synthetic import demo_scene

    assert frame_caption("sort", 12, "3 tracks") == "sort  frame 12  3 tracks"
    seq = demo_scene(seed=0, n_frames=2)
    b = seq.gt[0].boxes[0]
    graph = single_object.build_graph(single_object.Params(
        init_box=(b[0] + b[2] / 2, b[1] + b[3] / 2, b[2], b[3])))
    from pgm.core.frame import FrameContext
    engine = Engine(graph, np.random.default_rng(0))
    rec = engine.step(FrameContext(1, seq.frames[0]))
    captions = []
    import pgm.app.overlay as overlay
    original = overlay.annotate
    overlay.annotate = lambda *a, **k: captions.append(k["text"]) or a[0]
    try:
        annotated_frame(engine, rec, seq.frames[0], np.asarray(b, float), None, False, score=0.93)
        annotated_frame(engine, rec, seq.frames[0], np.asarray(b, float), None, True, score=0.93)
    finally:
        overlay.annotate = original
    assert captions[0] == "single-object  frame 1  confidence 0.93"
    assert captions[1].startswith("single-object  frame 1  confidence 0.93  ESS ")


def test_a_detector_declares_the_scale_of_its_scores():
    from pgm.observation.detections import CallableDetector

    def plain(image):
        return np.zeros((0, 5))

    assert CallableDetector(plain).score_range.tolist() == [0.0, 1.0]
    plain.score_range = (-5, 140)
    assert CallableDetector(plain).score_range.tolist() == [-5.0, 140.0]
    plain.score_range = None
    assert CallableDetector(plain).score_range is None
    plain.score_range = (3, 1)
    with pytest.raises(InputError, match="score_range"):
        CallableDetector(plain)


# -- item 2: OpenCV's HOG people detector -------------------------------------------------
class _FakeHOG:
    """Stands in for cv2.HOGDescriptor: two overlapping windows and one apart, in the
    resized frame's pixels."""

    seen: list = []

    def setSVMDetector(self, w):  # noqa: N802 - OpenCV's name
        pass

    def detectMultiScale(self, image, **kw):  # noqa: N802 - OpenCV's name
        _FakeHOG.seen.append(image.shape)
        return (np.array([[100, 50, 64, 128], [104, 52, 64, 128], [300, 60, 64, 128]]),
                np.array([2.0, 1.0, 0.5]))


def test_hog_boxes_are_the_windows_less_their_margin_in_frame_pixels(monkeypatch):
    import cv2

    from pgm.observation import hog

    monkeypatch.setattr(cv2, "HOGDescriptor", _FakeHOG, raising=False)
    monkeypatch.setattr(cv2, "HOGDescriptor_getDefaultPeopleDetector", lambda: None,
                        raising=False)
    det = hog.HOGPeopleDetector(platt={"a": 2.0, "b": -1.0})
    _FakeHOG.seen.clear()
    d = det(1, np.zeros((480, 640, 3), np.uint8))
    s = 128 / (480 * hog.SMALLEST)  # a sixth of 480 px resized to the 128 px window
    assert _FakeHOG.seen[0][:2] == (round(480 * s), round(640 * s))
    assert len(d) == 2  # the two overlapping windows are one detection, the stronger kept
    x, y, w, h = np.array([100, 50, 64, 128]) / s
    np.testing.assert_allclose(d.boxes[0], [x + w / 4, y + h / 8, w / 2, h * 3 / 4])
    np.testing.assert_allclose(d.scores, 1 / (1 + np.exp(-(2 * np.array([2.0, 0.5]) - 1))))
    assert det.score_range.tolist() == [0.0, 1.0]


def test_hog_where_opencv_has_none_is_one_line(monkeypatch, mot, tmp_path, capsys):
    import cv2

    monkeypatch.delattr(cv2, "HOGDescriptor", raising=False)
    code, _, err = run_cli(capsys, "track", mot, "--detector", "hog", "--out", tmp_path / "r",
                           "--no-video")
    lines = [ln for ln in err.splitlines() if ln.startswith("pgm: error:")]
    assert code == 2 and len(lines) == 1
    assert "opencv-contrib-python-headless" in lines[0] and "FILE.py:FUNCTION" in lines[0]


@pytest.mark.skipif(not hog_available(),
                    reason="the installed OpenCV has no HOGDescriptor (OpenCV 5's main wheel; "
                           "opencv-contrib-python-headless has it)")
def test_hog_finds_the_people_of_a_real_frame():
    from conftest import SHARED_DATA

    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.observation.detections import match_detections
    from pgm.observation.hog import HOGPeopleDetector
    if not (SHARED_DATA / "TUD-Campus").is_dir():
        pytest.skip(f"{SHARED_DATA / 'TUD-Campus'} not found")
    src = open_source(SHARED_DATA / "TUD-Campus")
    gt = load_mot(src.gt_path, kind="gt")
    number, image = next(iter(src.frames()))
    d = HOGPeopleDetector()(number, image)
    counts = match_detections(d, gt.at(number)[1], criterion="iou", iou_min=0.3)
    assert counts.tp >= 1 and np.all((d.scores > 0) & (d.scores < 1))
