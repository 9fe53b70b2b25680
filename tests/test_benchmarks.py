"""The benchmarks' shared timing loop reports what the runner reports (same seed)."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from pgm.app.runner import track
from pgm.inference import Engine
from pgm.models import single_object
from pgm.synthetic import demo_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _common import time_engine  # noqa: E402


def test_time_engine_boxes_equal_the_runner_boxes():
    seq = demo_scene(seed=0, n_frames=8)
    x, y, w, h = seq.box(0, 1)
    graph = single_object.build_graph(single_object.Params(init_box=(x + w / 2, y + h / 2, w, h)))
    frames = [(k + 1, img) for k, img in enumerate(seq.frames)]
    boxes, secs, _ = time_engine(Engine(graph, np.random.default_rng(3)), frames)
    result = track(frames, graph, rng=np.random.default_rng(3), progress=False)
    np.testing.assert_array_equal(boxes, result.boxes)
    assert secs > 0


@pytest.mark.slow
def test_plates_benchmark_quick_prints_its_table():
    """``benchmarks/plates.py --quick`` runs and prints one row per (K, N) of its tiny grid,
    with the plate and separate-engine timings (no wall-clock thresholds)."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, str(root / "benchmarks" / "plates.py"), "--quick"],
                         cwd=root, capture_output=True, text=True, timeout=300, check=True).stdout
    lines = out.splitlines()
    assert lines[0].startswith("machine:")
    header = next(i for i, line in enumerate(lines) if line.split()[:2] == ["K", "N"])
    assert set(lines[header + 1].replace(" ", "")) == {"-"}
    rows = []
    for line in lines[header + 2:]:
        if not line.strip():
            break
        rows.append(line.split())
    assert [r[:2] for r in rows] == [["1", "20"], ["3", "20"]]
    for r in rows:
        assert len(r) == 9
        values = [float(v) for v in r[2:]]
        assert all(np.isfinite(values)) and min(values[:3]) > 0
    assert "goals (reported, not asserted):" in out


def test_mot_sequences_set_option_reads_json_values_and_refuses_unknown_fields():
    import pytest
    from mot_sequences import parse_overrides

    assert parse_overrides(["sigma_log_h=0.15", "score_model=off", "particles_per_target=900"]) \
        == {"sigma_log_h": 0.15, "score_model": "off", "particles_per_target": 900}
    for bad in (["no_such_field=1"], ["sigma_log_h"]):
        with pytest.raises(SystemExit, match="FIELD=VALUE"):
            parse_overrides(bad)


def test_detection_errors_matches_every_scored_truth_at_most_once(shared_data, monkeypatch):
    """The error table's pairs are one-to-one: no more pairs than scored truths, each
    pair's errors finite; and the ground truth matched against itself (every box its
    own perfect detection) pairs every scored box with zero error."""
    import detection_errors as de

    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source

    seq = shared_data / "TUD-Campus"
    e = de.errors(seq)
    gt = load_mot(open_source(seq).gt_path, kind="gt")
    n = len(e["log_h"])
    assert 0 < n <= int(gt.scored.sum())
    keys = ("foot_x", "foot_y", "centre_y", "log_h")
    assert all(np.all(np.isfinite(e[k])) and len(e[k]) == n for k in keys)

    class Truth:
        table = gt.subset(gt.scored)

    monkeypatch.setattr(de, "make_detector", lambda spec, src: Truth())
    same = de.errors(seq)
    assert len(same["log_h"]) == int(gt.scored.sum())
    assert max(np.abs(same[k]).max() for k in keys) < 1e-9
    # the score table: the truth as its own detections (scored in file order) is on a
    # person in every decile, and a person still there in the next frame is found again
    from dataclasses import replace

    Truth.table = replace(Truth.table, conf=np.arange(len(Truth.table.conf), dtype=float))
    on, found = de.score_deciles(seq)
    np.testing.assert_array_equal(on, np.ones(10))
    assert found.min() > 0.8


def test_confidence_benchmark_is_calibrated_on_data_drawn_from_its_own_model(monkeypatch,
                                                                               capsys):
    """Oracle for ``benchmarks/confidence.py``'s loop: three "videos" of 1500, 3000 and
    6000 frames whose hits are drawn from a logistic of the two features. Fitted on two
    and scored on the third, the held-out predictions are calibrated, so both printed
    pooled ECEs (videos weighted equally, frames weighted equally) are small: a bin
    holding a tenth of the weight has a hit rate with a standard error of at most
    sqrt(0.25 / 450) ~ 0.024 (the shortest video's share), and 0.06 is 2.5 of them. A
    constant is not (0.2 or more: the videos' hit rates differ by construction)."""
    import re

    import confidence

    rng = np.random.default_rng(0)
    shift = {"a": -1.0, "b": 0.0, "c": 1.0}  # per-video feature level: hit rates differ
    frames = {"a": 1500, "b": 3000, "c": 6000}

    def fake_collect(name, seeds, fps=None):
        n = frames[name]
        x = np.column_stack([rng.normal(2.0 + shift[name], 0.6, n), rng.normal(-2.0, 0.5, n)])
        y = rng.uniform(size=n) < confidence.sigmoid(-7.0 + 3.5 * x[:, 0] - 0.2 * x[:, 1])
        return x, y, np.full(n, 0.5)

    monkeypatch.setattr(confidence, "sequences", lambda *a, **k: {n: n for n in shift})
    monkeypatch.setattr(confidence, "collect", fake_collect)
    monkeypatch.setattr(sys, "argv", ["confidence.py", "--seeds", "1"])
    confidence.main()
    out = capsys.readouterr().out
    pooled = re.findall(r"weighted equally.*?: ECE ([0-9.]+), Brier [0-9.]+ \(constant: ECE "
                        r"([0-9.]+)", out)
    assert len(pooled) == 2, out  # videos weighted equally, frames weighted equally
    assert all(float(e) < 0.06 and float(e_const) > 0.2 for e, e_const in pooled), pooled
    assert "mean held-out ECE per video" in out


@pytest.mark.slow
def test_mot_sequences_no_peers_prints_only_the_toolkit_rows(shared_data):
    """``--no-peers`` (for sweeps) prints the PHD and VB-PHD rows of the sequence, with
    finite scores, and no peer row."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, str(root / "benchmarks" / "mot_sequences.py"),
                          "--sequences", "TUD-Campus", "--no-peers"],
                         capture_output=True, text=True, check=True).stdout
    rows = [line.split() for line in out.splitlines() if line.strip().startswith("TUD-Campus")]
    assert [r[1] for r in rows] == ["PHD", "VB-PHD"]
    assert all(-1.0 <= float(r[2]) <= 1.0 and 0.0 <= float(r[3]) <= 1.0 for r in rows)
    assert not any(p in out for p in ("SORT", "ByteTrack", "OC-SORT"))


@pytest.mark.slow
def test_classic_trackers_benchmark_prints_the_cores_and_their_speed(shared_data):
    """``benchmarks/classic_trackers.py`` on one sequence without the peers: a row per core
    (sort, bytetrack, ocsort) with finite MOTA and IDF1, and a speed row per core."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, str(root / "benchmarks" / "classic_trackers.py"),
                          "--sequences", "TUD-Campus", "--repeats", "1", "--no-peers"],
                         capture_output=True, text=True, check=True).stdout
    rows = [line.split() for line in out.splitlines() if line.strip().startswith("TUD-Campus")]
    scores = [r for r in rows if len(r) == 8]
    speed = [r for r in rows if len(r) == 7]
    assert [r[1] for r in scores] == ["sort", "bytetrack", "ocsort"]
    assert all(-1.0 <= float(r[2]) <= 1.0 and 0.0 <= float(r[3]) <= 1.0 for r in scores)
    assert [r[1] for r in speed] == ["sort", "bytetrack", "ocsort"]
    assert all(float(r[3]) > 0 for r in speed)


@pytest.mark.slow
def test_desk_benchmark_prints_a_row_per_tracker():
    """``benchmarks/desk_eval.py`` on one short video without the peers: a row per config,
    each AUC in [0, 1] (no wall-clock thresholds)."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, str(root / "benchmarks" / "desk_eval.py"), "--videos",
                          "1", "--frames", "20", "--no-peers", "--appearance",
                          "cf(context_rate=0.05)"],
                         cwd=root, capture_output=True, text=True, timeout=300, check=True).stdout
    rows = [line for line in out.splitlines() if line.strip().startswith(("DEFAULT", "+", "size",
                                                                          "appearance"))]
    assert len(rows) == 5
    for row in rows:
        auc = float(row.split()[-3])
        assert 0.0 <= auc <= 1.0


def test_robustness_candidates_are_their_own_fields_and_one_is_the_default():
    """Every ``ocsort_colour`` candidate is OC-SORT's core with colour and its own fields
    (not the module's defaults, which move with each choice), and the candidate named
    the default builds exactly ``ocsort_colour.Params()``."""
    from dataclasses import asdict, replace

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "benchmarks"))
    import robustness

    from pgm.models import ocsort, ocsort_colour

    module, fields = robustness.CANDIDATES[robustness.DEFAULT]
    assert module == "ocsort_colour"
    assert asdict(replace(robustness.base_params(module), **fields)) == \
        asdict(ocsort_colour.Params())
    base = robustness.base_params("ocsort_colour")
    assert type(base) is ocsort.Params and base.fill_births is False and base.appearance == "colour"
    module, fields = robustness.CANDIDATES["ocsort-colour quantile 0.2 hits"]
    got = replace(base, **fields)
    assert (got.fill_gaps, got.birth_iou, got.noise_per) == (0.0, 1.0, "second")


@pytest.mark.slow
def test_robustness_benchmark_prints_a_table_per_kind_and_the_choice(shared_data, tmp_path):
    """``benchmarks/robustness.py`` on three sequences (the synthetic scene, whose folder
    every kind's task reads, written once before two workers start), three kinds (half
    the frame rate: each cell the mean over both shares of the frames), two candidates,
    without the peers: a table per kind, a rank-reading candidate's score-map row the same
    as its unperturbed row (copied, as the script says), the leave-one-out rows; the cache
    makes a second call run nothing."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    cmd = [sys.executable, str(root / "benchmarks" / "robustness.py"), "--sequences",
           "TUD-Campus,TUD-Stadtmitte,synthetic", "--kinds", "none,rank,fps/2", "--candidates",
           "ocsort-colour (detector scores),ocsort-colour quantile 0.2 hits", "--no-peers",
           "--jobs", "2", "--cache", str(tmp_path / "cache.jsonl"), "--work", str(tmp_path)]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=True).stdout
    assert "kind none: MOTA / IDF1 / HOTA" in out and "kind fps/2: MOTA / IDF1 / HOTA" in out
    tables = out.split("kind ")
    none = next(t for t in tables if t.startswith("none:"))
    rank = next(t for t in tables if t.startswith("rank:"))
    row = lambda t: next(line for line in t.splitlines() if line.strip().startswith(  # noqa: E731
        "TUD-Campus")).split()
    # cells "MOTA / IDF1 / HOTA": tokens 1-5 the detector-score candidate, 6-10 the
    # quantile one (the same under the rank map: its unperturbed row stands for it)
    for t in (none, rank):
        assert all(-1.0 <= float(v) <= 1.0 for v in row(t)[1:11] if v != "/")
    assert row(none)[6:11] == row(rank)[6:11]
    assert "leave one sequence out, criterion mean" in out
    assert " error" not in out and "Error" not in out
    # half the frame rate: the mean over both shares of the frames, each run
    cached = [json.loads(line) for line in (tmp_path / "cache.jsonl").read_text().splitlines()]
    half = [r for r in cached if r["kind"] == "fps/2"]
    assert len(half) == 6 and all(r["phases"] == 2 for r in half)
    for q in ("TUD-Campus", "TUD-Stadtmitte", "synthetic"):
        assert (tmp_path / q / "fps-2" / "seqinfo.ini").is_file()
        assert (tmp_path / q / "fps-2-p1" / "seqinfo.ini").is_file()
    synthetic = [line for line in none.splitlines() if line.strip().startswith("synthetic")]
    assert len(synthetic) == 1 and float(synthetic[0].split()[6]) > 0.5  # quantile: MOTA
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=True).stdout
    assert "0 sequence x kind tasks to run" in again


def test_detectors_benchmark_wraps_a_function_at_no_cost_to_the_tracks(shared_data):
    """``benchmarks/detectors.py`` on TUD-Campus: a row per detector; MOG2 wrapped as a
    user's function (``CallableDetector``) tracks exactly as MOG2 itself."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, str(root / "benchmarks" / "detectors.py"),
                          "--sequences", "TUD-Campus"], capture_output=True, text=True,
                         check=True).stdout
    rows = {r[1]: r for r in (line.split() for line in out.splitlines())
            if r and r[0] == "TUD-Campus"}
    assert list(rows) == ["public", "mog2", "yours"]
    assert rows["public"][5:7] == ["+0.000", "+0.000"]
    assert rows["mog2"][2:5] == rows["yours"][2:5]  # the same tracks' scores
    assert all(float(r[7]) > 0 and float(r[8]) > 0 for r in rows.values())


SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.mark.skipif(not (SHARED / "TUD-Campus").is_dir() or not (SHARED / "David").is_dir(),
                    reason="../shared/data (TUD-Campus, David, MOT16-11) is not there")
def test_speed_benchmark_prints_its_tables():
    """``benchmarks/speed.py`` on a small input prints each section's table with finite
    timings and ratios (no wall-clock thresholds)."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run(
        [sys.executable, str(root / "benchmarks" / "speed.py"), "--sequences", "TUD-Campus",
         "--sot", "David", "--frames", "15", "--repeats", "1", "--no-peers", "--seeds", "1",
         "--camera-frames", "8", "--phd-particles", "1000", "--cores", "sort",
         "--memory-frames", "40"],
        cwd=root, capture_output=True, text=True, timeout=600, check=True).stdout
    lines = out.splitlines()

    def row(prefix):
        hit = [ln for ln in lines if ln.strip().startswith(prefix)]
        assert hit, f"no row {prefix!r} in:\n{out}"
        return hit[0].split()

    decode = row("decode only")
    assert float(decode[-2]) == 1.0 and float(decode[-4]) > 0   # the baseline's own ratio
    for label in ("ocsort-colour (default): inference", "ocsort-colour (default): end to end",
                  "sort: inference", "sort: end to end"):
        r = row(label)
        assert np.isfinite(float(r[-4])) and float(r[-4]) > 0 and float(r[-2]) > 0
    assert "resident memory over one run" in out
    memory = [row(str(t)) for t in (10, 20, 40)]  # a quarter, a half, the whole stream
    assert all(float(m[1]) > 0 and float(m[2]) > 0 for m in memory)
    assert "MiB per 1 000 frames" in out
    cam = [row("before (640 wide"), row("now (defaults")]
    assert all(float(c[-3]) >= 0 for c in cam)
    assert float(row("David")[3]) > 0
    phd = row("1000")
    assert float(phd[1]) > 0 and float(phd[2]) > 0
    curve = [row(str(n)) for n in (250, 20000)]  # the speed-accuracy curve's ends
    assert all(len(c) == 7 and float(c[1]) > 0 and float(c[4]) > 0 for c in curve)
    # at equal accuracy, against the README's Stone Soup row (no peers here): a particle
    # count at or below its OSPA and the ratio of the times, or "not reached"
    assert "README's figures" in out
    equal = [ln for ln in lines if ln.strip().startswith("1000 ")
             and ln.count("N=") + ln.count("not reached") == 4]
    assert equal, out


def test_appearance_eval_bar_rows_give_the_margin_and_mark_a_verdict_the_seeds_carry():
    """The single-object bar summary: margin = the default's mean AUC over seeds − the best
    peer's; within the bar at ≥ −0.05; "(seeds)" where the margin is within two standard
    errors of the bar."""
    import appearance_eval as ae

    def scores(aucs):
        s = ae.Scores()
        s.aucs = list(aucs)
        return s

    peers = {"MIL": scores([0.60]), "CSRT": scores([0.50])}
    rows = ae.bar_rows({"far": (scores([0.70, 0.72, 0.71]), peers),  # +0.11, sure
                        "below": (scores([0.40, 0.41, 0.42]), peers),  # -0.19, sure
                        "luck": (scores([0.46, 0.66, 0.56]), peers)})  # -0.04 ± 0.058
    by = {r[0]: r for r in rows}
    assert by["far"][2] == "MIL 0.600" and by["far"][3] == "+0.110" and by["far"][4] == "yes"
    assert by["below"][4] == "no"
    assert by["luck"][3] == "-0.040" and by["luck"][4] == "yes (seeds)"
    assert by["far"][1] == "0.710 ± 0.006"
    assert by["far"][5] == ""  # not measured
    s = scores([0.6])
    s.first_size_aucs = [0.7, 0.8]
    assert ae.bar_rows({"fixed": (s, peers)})[0][5] == "0.750"


def test_appearance_eval_first_size_keeps_the_centres_at_the_first_frames_size():
    """The fixed-size reading: each box's centre kept, its size the first frame's."""
    import appearance_eval as ae

    got = ae.first_size([[10.0, 20.0, 4.0, 6.0], [0.0, 0.0, 10.0, 10.0]], [1, 2, 8.0, 2.0])
    np.testing.assert_allclose(got, [[8.0, 22.0, 8.0, 2.0], [1.0, 4.0, 8.0, 2.0]])
