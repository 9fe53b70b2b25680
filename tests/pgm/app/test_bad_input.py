"""Issue 12: no bad input becomes an internal error; no run leaves a folder that lies.

The matrix runs every subcommand against every class of malformed input, built on small
files written here, and asserts exit code 2, exactly one stderr line ``pgm: error: ...``
naming the problem, no traceback, and no result file presented as complete. The other
tests close the issue's defects one by one.
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from cli_run import run_cli

from pgm.io.video import write_image_sequence, write_seqinfo
from pgm.synthetic import demo_scene, multi_target_scene

N_FRAMES = 6



def assert_one_line_error(code, err, needle=""):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("pgm: error: "), err
    assert "Traceback" not in err and "internal error" not in err
    assert needle.lower() in lines[0].lower(), (needle, lines[0])


def assert_no_complete_results(out: Path):
    """A folder the failed run created holds nothing presented as a finished run."""
    if not out.is_dir():
        return
    assert not (out / "metrics.json").exists()
    assert not (out / "model.json").exists()
    run = out / "run.json"
    if run.exists():
        assert json.loads(run.read_text())["complete"] is False


# -- the files ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Small good and bad inputs (a few KB each), written once for the module."""
    d = tmp_path_factory.mktemp("bad")
    f: dict[str, Path] = {}
    f["seq"] = d / "seq"
    demo_scene(seed=0, n_frames=N_FRAMES).write_otb(f["seq"])
    f["gt"] = f["seq"] / "groundtruth_rect.txt"
    f["mot"] = d / "mot"
    multi_target_scene(seed=0, n_frames=N_FRAMES).write_mot(f["mot"], rng=0, sigma=1.0,
                                                            clutter_rate=0.5)
    f["empty_dir"] = d / "empty_dir"
    f["empty_dir"].mkdir()
    f["empty_file"] = d / "empty.txt"
    f["empty_file"].write_text("")
    f["text"] = d / "notes.txt"
    f["text"].write_text("hello world\nthis is not a table\n")
    f["random_video"] = d / "random.mp4"
    f["random_video"].write_bytes(np.random.default_rng(0).integers(0, 256, 4000,
                                                                     dtype=np.uint8).tobytes())
    # a real MP4 cut short: FFmpeg's "moov atom not found"
    vid = d / "full.mp4"
    writer = cv2.VideoWriter(str(vid), cv2.VideoWriter_fourcc(*"mp4v"), 10, (64, 48))
    for k in range(8):
        writer.write(np.full((48, 64, 3), 30 * k, np.uint8))
    writer.release()
    f["truncated_video"] = d / "truncated.mp4"
    f["truncated_video"].write_bytes(vid.read_bytes()[:600])
    f["image_file"] = next(iter(sorted((f["seq"] / "img").iterdir())))
    # a sequence with a corrupt frame 3, and one whose frame 4 changes size
    f["corrupt_frame"] = d / "corrupt_frame"
    shutil.copytree(f["seq"], f["corrupt_frame"])
    sorted((f["corrupt_frame"] / "img").iterdir())[2].write_bytes(b"not a png")
    f["size_change"] = d / "size_change"
    shutil.copytree(f["seq"], f["size_change"])
    victim = sorted((f["size_change"] / "img").iterdir())[3]
    cv2.imwrite(str(victim), np.zeros((60, 90, 3), np.uint8))
    # MOT folders with a bad seqinfo.ini
    for key, line in [("fps_huge", "frameRate=1e300"), ("fps_tiny", "frameRate=1e-300"),
                      ("fps_text", "frameRate=fast"), ("len_huge", "seqLength=1e300"),
                      ("no_section", None)]:
        g = d / f"mot_{key}"
        shutil.copytree(f["mot"], g)
        ini = g / "seqinfo.ini"
        if line is None:
            ini.write_text("name=x\nframeRate=30\n")
        else:
            k = line.split("=")[0]
            ini.write_text("\n".join(line if ln.startswith(k + "=") else ln
                                     for ln in ini.read_text().splitlines()) + "\n")
        f[f"mot_{key}"] = g
    # annotation files
    f["gt_text_line"] = d / "gt_bad" / "groundtruth_rect.txt"
    f["gt_text_line"].parent.mkdir()
    f["gt_text_line"].write_text("10,10,5,5\nhello world\n")
    f["gt_six_columns"] = d / "boxes.txt"  # OTB boxes with two columns too many
    f["gt_six_columns"].write_text("205,151,17,50,3,4\n204,150,17,50,3,4\n")
    f["gt_nan_only"] = d / "gt_nan" / "groundtruth_rect.txt"
    f["gt_nan_only"].parent.mkdir()
    f["gt_nan_only"].write_text("NaN,NaN,NaN,NaN\n0,0,0,0\n")
    f["det_nan_score"] = d / "det_nan.txt"
    f["det_nan_score"].write_text("1,-1,10,10,5,5,nan\n")
    f["det_text"] = d / "det_text.txt"
    f["det_text"].write_text("1,-1,10,10,5,5,0.9\n2,-1,oops\n")
    f["pred_dup"] = d / "pred_dup.txt"
    f["pred_dup"].write_text("1,1,10,10,5,5,1,-1,-1,-1\n1,1,11,10,5,5,1,-1,-1,-1\n")
    f["pred_ok"] = d / "pred_ok.txt"
    f["pred_ok"].write_text("1,1,10,10,5,5,1,-1,-1,-1\n")
    f["pred_inf"] = d / "pred_inf.txt"
    f["pred_inf"].write_text("1,1,10,10,inf,5,1,-1,-1,-1\n")
    # model files
    f["model_not_json"] = d / "broken.json"
    f["model_not_json"].write_text("{not json")
    f["model_wrong_format"] = d / "other.json"
    f["model_wrong_format"].write_text(json.dumps({"format": "something-else"}))
    f["model_bad_factor"] = d / "bad_factor.json"
    f["model_bad_factor"].write_text(json.dumps(
        {"format": "pgm-factor-graph", "version": 1, "name": "x", "meta": {},
         "variables": [{"name": "object", "dim": 4}],
         "factors": [{"type": "GaussianPrior", "variables": ["object"], "params": 7}]}))
    from pgm.models import colour_pf

    f["model_bad_engine"] = d / "bad_engine.json"
    colour_pf.build_graph(colour_pf.Params(init_box=(20.0, 20.0, 10.0, 10.0))).save(
        f["model_bad_engine"])
    saved = json.loads(f["model_bad_engine"].read_text())
    saved["meta"]["engine"]["ess_threshold"] = "abc"
    f["model_bad_engine"].write_text(json.dumps(saved))
    f["model_dir"] = d / "model_dir.json"
    f["model_dir"].mkdir()
    # DBN files
    f["dbn_text"] = d / "dbn_text.npz"
    f["dbn_text"].write_text("hello\n")
    f["dbn_pickle"] = d / "dbn_pickle.npz"
    f["dbn_pickle"].write_bytes(pickle.dumps({"hidden": (4, 3)}))
    f["dbn_no_hidden"] = d / "dbn_no_hidden.npz"
    np.savez(f["dbn_no_hidden"], header=np.array(json.dumps({"format": "pgm-dbn-v1"})),
             **{f"w{k}": np.zeros(2) for k in range(6)})
    f["dbn_nan"] = d / "dbn_nan.npz"
    np.savez(f["dbn_nan"], header=np.array(json.dumps(
        {"format": "pgm-dbn-v1", "hidden": [2, 2], "platt": [1, 0], "prior": 0.5,
         "features": {"n_orient": 1, "cells": [1, 1]}})),
        w0=np.full((1, 2), np.nan), w1=np.zeros(2), w2=np.zeros((2, 2)), w3=np.zeros(2),
        w4=np.zeros((2, 1)), w5=np.zeros(1))
    f["a_file"] = d / "a_file"
    f["a_file"].write_text("x")
    f["a_dir_png"] = d / "dir.png"
    f["a_dir_png"].mkdir()
    return f


T = "track"
# (case, argv whose {names} are formatted with the files written above and {out} with a
# fresh output path, text the one-line message must contain)
MATRIX = [
    # -- track: sources
    ("missing source", [T, "{empty_dir}/nope.mp4", "--init", "1,1,5,5"], "no such file"),
    ("empty folder", [T, "{empty_dir}", "--init", "1,1,5,5"], "no image files"),
    ("random bytes as video", [T, "{random_video}", "--init", "1,1,5,5"], "random.mp4"),
    ("truncated mp4 (moov atom)", [T, "{truncated_video}", "--init", "1,1,5,5"],
     "truncated.mp4"),
    ("single image as source", [T, "{image_file}", "--init", "1,1,5,5"], "single image"),
    ("corrupt frame 3", [T, "{corrupt_frame}"], "0003.png"),
    ("frame 4 changes size", [T, "{size_change}"], "90x60"),
    ("seqinfo frameRate=1e300", [T, "{mot_fps_huge}", "--model", "phd"], "frameRate"),
    ("seqinfo frameRate=1e-300", [T, "{mot_fps_tiny}", "--model", "phd"], "frameRate"),
    ("seqinfo frameRate=fast", [T, "{mot_fps_text}", "--model", "phd"], "frameRate"),
    ("seqinfo seqLength=1e300", [T, "{mot_len_huge}", "--model", "phd"], "seqLength"),
    ("seqinfo without [Sequence]", [T, "{mot_no_section}", "--model", "phd"], "seqinfo"),
    # -- track: boxes
    ("box outside the image", [T, "{seq}", "--init", "1000,1000,10,10"], "outside"),
    ("box of zero area", [T, "{seq}", "--init", "5,5,0,10"], "zero or negative area"),
    ("box with NaN", [T, "{seq}", "--init", "5,nan,10,10"], "finite"),
    ("box of three numbers", [T, "{seq}", "--init", "5,5,10"], "four"),
    # -- track: annotations and detections
    ("gt with a text line", [T, "{seq}", "--gt", "{gt_text_line}"], "groundtruth_rect.txt:2"),
    ("gt without any box", [T, "{seq}", "--gt", "{gt_nan_only}"], "no annotated box"),
    ("gt empty file", [T, "{seq}", "--gt", "{empty_file}"], "no annotated box"),
    ("gt of six columns", [T, "{seq}", "--gt", "{gt_six_columns}"],
     "boxes.txt (read as MOTChallenge rows frame,id,x,y,w,h"),
    ("detections with NaN score", [T, "{mot}", "--model", "phd", "--detections",
                                   "{det_nan_score}"], "not finite"),
    ("detections with text", [T, "{mot}", "--model", "phd", "--detections", "{det_text}"],
     "det_text.txt:2"),
    # -- track: parameters
    ("--particles 0", [T, "{seq}", "--particles", "0"], "--particles"),
    ("--particles ten", [T, "{seq}", "--particles", "ten"], "--particles"),
    ("--particles 1e9 (memory)", [T, "{seq}", "--model", "colour-pf", "--particles",
                                  "1000000000"], "GB"),
    ("--particles 1e7, 1 GB cap", [T, "{seq}", "--model", "colour-pf", "--particles",
                                   "10000000", "--memory-limit", "1G"], "memory cap is 1 GB"),
    ("phd --particles 1e8 (memory)", [T, "{mot}", "--model", "phd", "--particles",
                                      "100000000"], "GB"),
    ("--memory-limit lots", [T, "{seq}", "--memory-limit", "lots"], "--memory-limit"),
    ("unknown model", [T, "{seq}", "--model", "kalman-magic"], "unknown model"),
    ("--parts 100", [T, "{seq}", "--model", "part-graph", "--parts", "100"], "--parts"),
    ("--scale-noise nan", [T, "{seq}", "--scale-noise", "nan"], "--scale-noise"),
    ("--scale-noise -1", [T, "{seq}", "--scale-noise", "-1"], "non-negative, got -1.0"),
    ("cf(bogus=1)", [T, "{seq}", "--appearance", "cf(bogus=1)"],
     "appearance cue 'cf': unknown option 'bogus'"),
    ("--dbn on single-object", [T, "{seq}", "--dbn", "{dbn_nan}"], "--dbn does not apply"),
    ("--per-track-noise on single-object", [T, "{seq}", "--per-track-noise"],
     "--per-track-noise does not apply"),
    ("--scores on colour-pf", [T, "{seq}", "--model", "colour-pf", "--scores", "mixture"],
     "--scores does not apply"),
    ("--appearance on phd", [T, "{mot}", "--model", "phd", "--appearance", "template"],
     "--appearance does not apply"),
    ("--init on phd", [T, "{mot}", "--model", "phd", "--init", "1,1,5,5"], "--init"),
    ("unknown detector", [T, "{mot}", "--model", "phd", "--detector", "yolo"], "yolo"),
    ("--detector a missing file", [T, "{mot}", "--detector", "{empty_dir}/nosuch.py:f"],
     "nosuch.py: no such file"),
    ("--trails -1", [T, "{seq}", "--trails", "-1"], "--trails must be at least 0"),
    ("--seed -2", [T, "{seq}", "--seed", "-2"], "--seed must be at least 0"),
    ("--fps 0", [T, "{seq}", "--fps", "0"], "--fps must be a frame rate in [0.01, 10000]"),
    # -- track: model files
    ("model.json missing", [T, "{seq}", "--model", "{empty_dir}/model.json"], "not found"),
    ("model.json not JSON", [T, "{seq}", "--model", "{model_not_json}"], "broken.json"),
    ("model.json other format", [T, "{seq}", "--model", "{model_wrong_format}"], "format"),
    ("model.json bad factor", [T, "{seq}", "--model", "{model_bad_factor}"], "bad_factor"),
    ("model.json is a folder", [T, "{seq}", "--model", "{model_dir}"], "folder"),
    ("model.json engine setting not a number", [T, "{seq}", "--model", "{model_bad_engine}"],
     "bad_engine.json: ess_threshold must be in [0, 1], got 'abc'"),
    # -- track: DBN files
    ("DBN text file", [T, "{mot}", "--model", "phd", "--dbn", "{dbn_text}"],
     "not an .npz"),
    ("DBN pickle", [T, "{mot}", "--model", "phd", "--dbn", "{dbn_pickle}"], "pickle"),
    ("DBN without 'hidden'", [T, "{mot}", "--model", "phd", "--dbn", "{dbn_no_hidden}"],
     "'hidden'"),
    ("DBN NaN weights", [T, "{mot}", "--model", "phd", "--dbn", "{dbn_nan}"], "NaN"),
    # -- track: output paths
    ("--out an existing file", [T, "{seq}", "--out", "{a_file}"], "not a folder"),
    ("--out under a file", [T, "{seq}", "--out", "{a_file}/sub"], "a_file"),
    # -- eval
    ("eval: empty --pred", ["eval", "--gt", "{gt}", "--pred", "{empty_file}"], "no rows"),
    ("eval: missing --pred", ["eval", "--gt", "{gt}", "--pred", "{empty_dir}/t.txt"],
     "no such file"),
    ("eval: text --pred", ["eval", "--gt", "{gt}", "--pred", "{text}"], "notes.txt:1"),
    ("eval: duplicate rows", ["eval", "--gt", "{gt}", "--pred", "{pred_dup}"], "two boxes"),
    ("eval: infinite box", ["eval", "--gt", "{gt}", "--pred", "{pred_inf}"], "pred_inf.txt:1"),
    ("eval: malformed --gt", ["eval", "--gt", "{gt_text_line}", "--pred", "{pred_ok}"],
     "groundtruth_rect.txt"),
    ("eval: --gt a folder", ["eval", "--gt", "{empty_dir}", "--pred", "{pred_ok}"],
     "not a file"),
    # -- graph
    ("graph: unknown model", ["graph", "kalman-magic", "--out", "{out}.png"], "kalman-magic"),
    ("graph: .gif", ["graph", "colour-pf", "--out", "{out}.gif"], ".gif"),
    ("graph: --out a folder", ["graph", "colour-pf", "--out", "{a_dir_png}"], "folder"),
    ("graph: --out under a file", ["graph", "colour-pf", "--out", "{a_file}/g.png"], "a_file"),
    ("graph: --parts 100", ["graph", "part-graph", "--parts", "100", "--out", "{out}.png"],
     "--parts"),
    ("graph: bad model.json", ["graph", "{model_bad_factor}", "--out", "{out}.png"],
     "bad_factor"),
    ("graph: --appearance on phd", ["graph", "phd", "--appearance", "cf", "--out",
                                    "{out}.png"], "--appearance"),
    # -- learn
    ("learn: missing --train", ["learn", "dbn", "--train", "{empty_dir}/nope", "--out",
                                "{out}.npz"], "nope"),
    ("learn: --train an OTB folder", ["learn", "dbn", "--train", "{seq}", "--out",
                                      "{out}.npz"], "groundtruth_rect.txt"),
    ("learn: --out not .npz", ["learn", "dbn", "--train", "{mot}", "--out", "{out}.txt"],
     ".npz"),
    ("learn: --out under a file", ["learn", "dbn", "--train", "{mot}", "--out",
                                   "{a_file}/m.npz"], "a_file"),
    # -- demo
    ("demo: --out an existing file", ["demo", "--out", "{a_file}"], "not a folder"),
    ("demo: --out under a file", ["demo", "--out", "{a_file}/d"], "a_file"),
    ("demo: --frames 0", ["demo", "--out", "{out}", "--frames", "0"], "--frames"),
]


def _argv(template, files, out):
    argv = [str(a).format(out=out, **{k: str(v) for k, v in files.items()}) for a in template]
    if argv[0] == "track":
        if "--out" not in argv:
            argv += ["--out", str(out)]
        argv += ["--quiet", "--no-video"]
    return argv


@pytest.mark.parametrize("case, template, needle", MATRIX, ids=[m[0] for m in MATRIX])
def test_bad_input_matrix(files, tmp_path, capsys, case, template, needle):
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, _argv(template, files, out))
    assert_one_line_error(code, err, needle)
    assert_no_complete_results(out)


def test_matrix_covers_every_subcommand():
    from pgm.app.cli import COMMANDS

    covered = {m[1][0] for m in MATRIX}
    assert covered == set(COMMANDS)


# -- defect 1: tiny boxes ------------------------------------------------------------
@pytest.mark.parametrize("box", ["205,151,1,1", "205,151,4,1", "205,151,1,4", "1,1,1,1",
                                 "320,240,1,1", "100,100,0.4,0.6"])
@pytest.mark.parametrize("cue", ["colour", "contrast", "fragments", "rings"])
def test_tiny_box_runs(files, tmp_path, capsys, box, cue):
    """A 1x1, 4x1 or sub-pixel box at the centre or the image corner tracks (an OpenCV
    size mismatch in the colour quantisation before)."""
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", "colour-pf",
                                    "--appearance", cue, "--init", box, "--out", tmp_path,
                                    "--quiet", "--no-video", "--max-frames", 3])
    if cue == "fragments" and code == 2:  # a 3x3 grid of a 1-pixel box may leave the image
        assert_one_line_error(code, err, "outside the image")
        return
    assert code == 0, err
    assert len((tmp_path / "tracks.txt").read_text().splitlines()) == 3


# -- defect 2: every model can be drawn ----------------------------------------------
@pytest.mark.parametrize("model", ["single-object", "colour-pf", "part-graph", "phd",
                                   "vb-phd"])
@pytest.mark.parametrize("ext", ["png", "dot"])
def test_graph_of_every_model(tmp_path, capsys, model, ext):
    out = tmp_path / f"g.{ext}"
    code, _, err = run_cli(capsys, ["graph", model, "--out", out])
    assert code == 0, err
    assert out.stat().st_size > 100


# -- defect 3: eval of an empty prediction --------------------------------------------
def test_eval_prints_missing_values(files, tmp_path, capsys):
    """A prediction with no overlap prints n/a (a TypeError in the table printer before),
    and an empty one is a one-line error (above, in the matrix)."""
    pred = tmp_path / "tracks.txt"
    pred.write_text("100,1,10,10,5,5,1,-1,-1,-1\n")
    code, stdout, err = run_cli(capsys, ["eval", "--gt", files["gt"], "--pred", pred])
    assert code == 0, err
    assert "n/a" in stdout


# -- defect 4: saved models ----------------------------------------------------------
def _saved_then_moved(files, tmp_path, capsys, *model_args) -> Path:
    """Track 2 frames with ``model_args``, then re-run the saved model from a new
    ``--init`` box; the first row of the second run is that box. The saved model."""
    first = tmp_path / "first"
    code, _, err = run_cli(capsys, ["track", files["seq"], *model_args, "--out", first,
                                    "--quiet", "--no-video", "--max-frames", 2])
    assert code == 0, err
    again = tmp_path / "again"
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", first / "model.json",
                                    "--init", "31,101,20,20", "--out", again, "--quiet",
                                    "--no-video", "--max-frames", 2])
    assert code == 0, err
    row = (again / "tracks.txt").read_text().splitlines()[0].split(",")
    assert [float(v) for v in row[2:6]] == [31, 101, 20, 20]  # --init was used
    return first / "model.json"


def test_saved_single_object_model_honours_init_and_refuses_options(files, tmp_path, capsys):
    saved = _saved_then_moved(files, tmp_path, capsys, "--model", "colour-pf")
    for opt in (["--appearance", "template"], ["--scale-noise", "0.1"], ["--parts", "2"]):
        code, _, err = run_cli(capsys, ["track", files["seq"], "--model", saved,
                                        "--init", "31,101,20,20", "--out", tmp_path / "x",
                                        "--quiet", *opt])
        assert_one_line_error(code, err, f"{opt[0]} does not apply to a saved model")


def test_a_saved_model_with_an_angle_and_redetection_moves_to_a_new_box(files, tmp_path,
                                                                        capsys):
    _saved_then_moved(files, tmp_path, capsys, "--redetect", "0.5", "--rotation-noise", "0.01")
    for opt, msg in ((["--redetect", "1.5"], "redetect must be a share in [0, 1]"),
                     (["--rotation-noise", "-1"], "must be non-negative")):
        code, _, err = run_cli(capsys, ["track", files["seq"], "--out", tmp_path / "x",
                                        "--quiet", *opt])
        assert_one_line_error(code, err, msg)


def test_saved_multi_target_model_reruns(files, tmp_path, capsys):
    first = tmp_path / "first"
    code, _, err = run_cli(capsys, ["track", files["mot"], "--model", "vb-phd", "--out", first,
                                    "--quiet", "--no-video"])
    assert code == 0, err
    again = tmp_path / "again"
    code, _, err = run_cli(capsys, ["track", files["mot"], "--model", first / "model.json",
                                    "--out", again, "--quiet", "--no-video"])
    assert code == 0, err
    saved = json.loads((again / "model.json").read_text())
    assert any(v["role"] == "noise" for v in saved["variables"])  # still the VB-PHD graph
    assert json.loads((again / "run.json").read_text())["complete"] is True


# -- defect 6: the memory estimate ---------------------------------------------------
def test_memory_estimate_grows_with_particles_and_frame_size():
    from pgm.app.runner import check_memory, estimate_memory
    from pgm.core.errors import InputError
    from pgm.models import colour_pf

    g = colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 10, 10)))
    small = estimate_memory(g, (320, 240), num_particles=100)
    assert small < estimate_memory(g, (320, 240), num_particles=10_000)
    assert small < estimate_memory(g, (1920, 1080), num_particles=100)
    # the reported 8.7 GB at 10 million particles: the estimate is at least that
    assert estimate_memory(g, (320, 240), num_particles=10_000_000) > 8.7e9
    with pytest.raises(InputError, match="needs about"):
        check_memory(g, (320, 240), num_particles=10_000_000, limit=1e9)
    assert check_memory(g, (320, 240), num_particles=100, limit=1e9) == small


# -- defect 9: stale outputs and symbolic links --------------------------------------
def test_rerun_removes_the_earlier_runs_results(files, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", "colour-pf", "--gt",
                                    files["gt"], "--out", out, "--quiet"])
    assert code == 0, err
    assert {"metrics.json", "annotated.mp4", "model.json"} <= {p.name for p in out.iterdir()}
    (out / "notes.md").write_text("mine")
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", "colour-pf", "--init",
                                    "31,101,20,20", "--out", out, "--quiet", "--no-video",
                                    "--max-frames", 2])
    assert code == 0, err
    names = {p.name for p in out.iterdir()}
    assert "metrics.json" not in names and "annotated.mp4" not in names  # no stale results
    assert (out / "notes.md").read_text() == "mine"  # other files are left alone
    assert len((out / "tracks.txt").read_text().splitlines()) == 2
    run = json.loads((out / "run.json").read_text())
    assert run["complete"] is True and run["frames"] == 2


def test_failed_run_leaves_no_stale_results(files, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, _ = run_cli(capsys, ["track", files["seq"], "--model", "colour-pf", "--gt",
                                  files["gt"], "--out", out, "--quiet", "--no-video"])
    assert code == 0
    code, _, err = run_cli(capsys, ["track", files["corrupt_frame"], "--model", "colour-pf",
                                    "--out", out, "--quiet", "--no-video"])
    assert_one_line_error(code, err, "0003.png")
    assert not (out / "metrics.json").exists() and not (out / "model.json").exists()
    run = json.loads((out / "run.json").read_text())
    assert run["complete"] is False and run["frames"] == 2
    assert run["stopped"].startswith("error:") and "0003.png" in run["stopped"]
    assert len((out / "tracks.txt").read_text().splitlines()) == 2


def test_tracks_symlink_is_not_followed(files, tmp_path, capsys):
    victim = tmp_path / "precious.txt"
    victim.write_text("do not overwrite\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "tracks.txt").symlink_to(victim)
    (out / "metrics.json").symlink_to(victim)
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", "colour-pf", "--gt",
                                    files["gt"], "--out", out, "--quiet", "--no-video"])
    assert code == 0, err
    assert victim.read_text() == "do not overwrite\n"
    assert not (out / "tracks.txt").is_symlink()
    assert len((out / "tracks.txt").read_text().splitlines()) == N_FRAMES


# -- defect 10: SIGTERM is handled like SIGINT ---------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_keeps_rows_and_a_playable_video(tmp_path, sig):
    seq = tmp_path / "seq"
    demo_scene(seed=0, n_frames=200).write_otb(seq)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "pgm.app.cli", "track", str(seq), "--model",
                             "colour-pf", "--particles", "50", "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    tracks = out / "tracks.txt"
    try:
        while proc.poll() is None and not (
                tracks.exists() and len(tracks.read_text().splitlines()) >= 5):
            time.sleep(0.02)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, err
    assert err.strip().splitlines()[-1].startswith(f"pgm: interrupted by {sig.name}")
    assert "Traceback" not in err
    rows = len(tracks.read_text().splitlines())
    assert 5 <= rows < 200
    run = json.loads((out / "run.json").read_text())
    assert run["complete"] is False and run["stopped"] == f"interrupted by {sig.name}"
    assert run["frames"] == rows
    assert not (out / "metrics.json").exists()
    cap = cv2.VideoCapture(str(out / "annotated.mp4"))
    decoded = 0
    while cap.read()[0]:
        decoded += 1
    cap.release()
    assert rows - 1 <= decoded <= rows  # finalised: every frame written before the signal


# -- defect 11: mid-sequence size changes (also in the matrix) -----------------------
def test_size_change_is_reported_by_the_source(files):
    from pgm.io.video import open_source

    with pytest.raises(ValueError, match="90x60"):
        for _ in open_source(files["size_change"]).frames():
            pass


# -- defect 12: one line on the terminal ---------------------------------------------
@pytest.mark.slow
def test_ffmpeg_and_warnings_are_one_line(files, tmp_path):
    """FFmpeg's own 'moov atom not found' never reaches the terminal (a fresh process:
    FFmpeg reads its log level once), and a toolkit warning is one ``pgm: warning:`` line
    without the source line Python's warnings module echoes."""
    res = subprocess.run([sys.executable, "-m", "pgm.app.cli", "track",
                          str(files["truncated_video"]), "--init", "1,1,5,5", "--out",
                          str(tmp_path / "o")], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PGM_DEBUG": ""})
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [res.stderr.strip()]
    assert "moov" not in res.stderr
    short = tmp_path / "short"
    shutil.copytree(files["mot"], short)
    ini = short / "seqinfo.ini"
    ini.write_text(ini.read_text().replace(f"seqLength={N_FRAMES}", "seqLength=3"))
    res = subprocess.run([sys.executable, "-m", "pgm.app.cli", "track", str(short), "--model",
                          "phd", "--out", str(tmp_path / "o2"), "--no-video"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pgm: warning: ") and "seqLength" in lines[0]


def test_python_warnings_become_one_line(monkeypatch, tmp_path, capsys):
    import warnings

    import pgm.app.cli as cli

    def noisy(args):
        warnings.warn("something odd\nacross lines", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setitem(cli.COMMANDS, "eval", noisy)
    code, _, err = run_cli(capsys, ["eval", "--gt", "x", "--pred", "y"])
    assert code == 0
    assert err.strip() == "pgm: warning: something odd across lines"


def test_image_sequence_helper_still_writes(tmp_path):
    """The writers used by the fixtures above are unchanged (a sanity check)."""
    write_image_sequence(tmp_path / "img1", [np.zeros((4, 4, 3), np.uint8)])
    write_seqinfo(tmp_path, name="x", fps=30, length=1, width=4, height=4)
    assert (tmp_path / "seqinfo.ini").read_text().count("frameRate=30") == 1


def test_a_saved_model_that_cannot_move_starts_where_saved_on_a_sequences_own_truth(
        files, tmp_path, capsys):
    """A saved model whose priors are not Gaussian priors over (cx, cy, w, h) (a variable
    without labels) cannot be moved to another first box: on a sequence with its own
    ground truth it starts where it was saved (and says so), where the user's --init asks
    to move it the run is refused in one line."""
    import pgm
    from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood

    model = tmp_path / "unlabelled.json"
    pgm.FactorGraph([pgm.Variable("obj", 4, role="part")],
                    [pgm.GaussianPrior("obj", mean=[60, 60, 20, 30], cov=0.0),
                     pgm.AR2Transition("obj", noise_std=[2, 2, 0, 0]),
                     ColourHistogramLikelihood("obj")], name="unlabelled").save(model)
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", model, "--out",
                                    tmp_path / "own", "--no-video", "--max-frames", "3"])
    assert code == 0, err
    assert "using the saved model's own start" in err
    code, _, err = run_cli(capsys, ["track", files["seq"], "--model", model, "--init",
                                    "31,101,20,20", "--out", tmp_path / "moved", "--quiet"])
    assert_one_line_error(code, err, "cannot move saved model")


def test_a_saved_motion_at_another_frame_rate_is_said(files, tmp_path, capsys):
    """The motion library's factors are discretised at their own frame rate and a saved
    model keeps it: run on a video of another rate, the run says so (it is not
    re-discretised); at the same rate, nothing."""
    import pgm
    from pgm.factors.motion import constant_velocity
    from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood

    labels = ("cx", "cy", "w", "h", "vx", "vy")
    model = tmp_path / "cv30.json"
    pgm.FactorGraph([pgm.Variable("box", 6, role="part", labels=labels)],
                    [pgm.GaussianPrior("box", mean=[60, 60, 20, 30, 0, 0],
                                       cov=np.diag([1, 1, 0, 0, 100, 100.0])),
                     constant_velocity("box", labels=labels, axes=[("cx", "vx"), ("cy", "vy")],
                                       q=2000.0, fps=30.0),
                     ColourHistogramLikelihood("box")], name="cv-colour",
                    meta={"output": "box"}).save(model)
    said = {}
    for fps in ("10", "30"):
        code, _, err = run_cli(capsys, ["track", files["seq"], "--model", model, "--fps", fps,
                                        "--out", tmp_path / fps, "--no-video",
                                        "--max-frames", "3"])
        assert code == 0, err
        said[fps] = "discretised at 30 frames/s (the video's is 10" in err
    assert said == {"10": True, "30": False}
