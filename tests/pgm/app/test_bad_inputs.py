"""Issue 26, items 13-18: the last bad inputs of a sweep of 688.

The matrix runs each case through ``pgm`` (in this process) and checks the exit code
(2), one ``pgm: error:`` line, no traceback, and that the message names the input at
fault (the option, the file and its line), not an internal parameter. Inputs that were
wrongly refused now run (``--init -3,10,20,20``). The other tests close the defects
that are not one message: a run that was silently wrong, a stale page, a hang, files
outside the run folder. API cases raise ``ValueError``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_run import run_cli

from pgm.app.cli import main
from pgm.synthetic import demo_scene, multi_target_scene

N_FRAMES = 6



def assert_names_the_input(code, err, *needles):
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("pgm: using")]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("pgm: error: "), err
    assert "Traceback" not in err and "internal error" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def _nested(depth: int) -> str:
    return "[" * depth + "]" * depth


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Small inputs, written once for the module."""
    d = tmp_path_factory.mktemp("bad26")
    f: dict[str, Path] = {"dir": d}
    f["seq"] = d / "seq"
    demo_scene(seed=0, n_frames=N_FRAMES).write_otb(f["seq"])
    f["mot"] = d / "mot"
    multi_target_scene(seed=0, n_frames=N_FRAMES).write_mot(f["mot"], rng=0, sigma=1.0,
                                                            clutter_rate=0.5)
    f["det_huge"] = d / "det_huge.txt"
    f["det_huge"].write_text("1,-1,10,10,5,5,0.9\n2,-1,1e300,1e300,5,5,0.9\n")
    f["gt_huge"] = d / "gt_huge" / "groundtruth_rect.txt"
    f["gt_huge"].parent.mkdir()
    f["gt_huge"].write_text("10,10,5,5\n1e300,10,5,5\n")
    f["dbn_deep"] = d / "dbn_deep.npz"
    np.savez(f["dbn_deep"], header=np.array(_nested(100_000)),
             **{f"w{k}": np.zeros(2) for k in range(6)})
    f["toml_seeds"] = d / "seeds.toml"
    f["toml_seeds"].write_text(f'seeds = 1000000000\nsequences = ["{f["seq"]}"]\n'
                               f'[[models]]\nname = "colour-pf"\n')
    f["toml_grid"] = d / "grid.toml"
    f["toml_grid"].write_text(f'seeds = 60000\nsequences = ["{f["seq"]}", "{f["mot"]}"]\n'
                              f'[[models]]\nname = "colour-pf"\n')
    return f


T = "track"
# (case, argv; {names} formatted with the files above and {out} with a fresh path,
# texts the one-line message must contain)
MATRIX = [
    # 13: bounded up front, the message names the option
    ("--appearance cf(padding=1e6)", [T, "{seq}", "--appearance", "cf(padding=1e6)"],
     ["--appearance 'cf(padding=1e6)'", "padding"]),
    ("--appearance gradient(n_orient=1e6)", [T, "{seq}", "--appearance",
                                             "gradient(n_orient=1e6)"],
     ["--appearance 'gradient(n_orient=1e6)'", "n_orient", "36"]),
    ("--appearance gradient(n_orient=1e400)", [T, "{seq}", "--model", "colour-pf",
                                               "--appearance", "gradient(n_orient=1e400)"],
     ["--appearance", "n_orient"]),
    ("--appearance colour(n_h=1e400)", [T, "{seq}", "--model", "colour-pf",
                                        "--appearance", "colour(n_h=1e400)"],
     ["--appearance", "n_h"]),
    ("multi-pf --appearance cf(padding=1e6)", [T, "{mot}", "--model", "multi-pf",
                                               "--appearance", "cf(padding=1e6)"],
     ["--appearance 'cf(padding=1e6)'"]),
    ("--drop-frames past the end", [T, "{mot}", "--model", "multi-pf", "--drop-frames",
                                     "99999999999-99999999999"], ["--drop-frames", "past"]),
    ("bench seeds = 1e9", ["bench", "{toml_seeds}", "--out", "{out}"],
     ["seeds.toml", "seeds = 1000000000"]),
    ("bench 120000 runs", ["bench", "{toml_grid}", "--out", "{out}"],
     ["grid.toml", "120000 runs"]),
    ("--init 1,1,1e308,1e308", [T, "{seq}", "--init", "1,1,1e308,1e308"],
     ["--init", "1e+308"]),
    ("det.txt row with 1e300", [T, "{mot}", "--model", "phd", "--detections", "{det_huge}"],
     ["det_huge.txt:2"]),
    ("gt row with 1e300", [T, "{seq}", "--gt", "{gt_huge}"], ["groundtruth_rect.txt:2"]),
    # 14: internal errors before
    ("DBN header nested 100000 deep", [T, "{mot}", "--model", "phd", "--dbn", "{dbn_deep}"],
     ["dbn_deep.npz", "nested too deeply"]),
    # 15: --out ''
    ("track --out ''", [T, "{seq}", "--out", ""], ["--out is empty"]),
    ("demo --out ''", ["demo", "--out", ""], ["--out is empty"]),
    ("graph --out ''", ["graph", "colour-pf", "--out", ""], ["--out is empty"]),
    ("learn dbn --out ''", ["learn", "dbn", "--train", "{mot}", "--out", ""],
     ["--out is empty"]),
    ("bench --out ''", ["bench", "{toml_seeds}", "--out", ""], ["--out is empty"]),
    ("track SOURCE ''", [T, "", "--out", "{out}"], ["SOURCE is empty"]),
    ("report ''", ["report", ""], ["DIR is empty"]),
]


def _argv(template, files, out):
    argv = [str(a).format(out=out, **{k: str(v) for k, v in files.items()})
            for a in template]
    if argv[0] == T:
        if "--out" not in argv:
            argv += ["--out", str(out)]
        argv += ["--quiet", "--no-video"]
    return argv


@pytest.mark.parametrize("case, template, needles", MATRIX, ids=[m[0] for m in MATRIX])
def test_bad_input_names_the_input(files, tmp_path, capsys, case, template, needles):
    code, _, err = run_cli(capsys, _argv(template, files, tmp_path / "out"))
    assert_names_the_input(code, err, *needles)


def test_gpdm_header_nested_too_deeply(files, tmp_path, capsys):
    pytest.importorskip("torch")
    from pgm.dynamics.gpdm import _ARRAYS

    deep = tmp_path / "gpdm_deep.npz"
    np.savez(deep, header=np.array(_nested(100_000)), **{k: np.zeros(2) for k in _ARRAYS})
    code, _, err = run_cli(capsys, [T, files["mot"], "--model", "gpdm", "--gpdm", deep,
                                    "--out", tmp_path / "out", "--quiet", "--no-video"])
    assert_names_the_input(code, err, "gpdm_deep.npz", "nested too deeply")


# -- 13/17: inputs that were refused or went wrong, now run --------------------------------
def test_init_left_of_the_image_is_accepted(files, tmp_path, capsys):
    """``--init -3,10,20,20`` (a box partly left of the image) parses as a value."""
    code, _, err = run_cli(capsys, [T, files["seq"], "--init", "-3,10,20,20", "--out",
                                    tmp_path, "--quiet", "--no-video"])
    assert code == 0, err
    first = (tmp_path / "tracks.txt").read_text().splitlines()[0].split(",")
    assert [float(v) for v in first[2:6]] == [-3.0, 10.0, 20.0, 20.0]


def test_drop_frames_beyond_the_end_are_cut_at_the_last_frame(files, tmp_path, capsys):
    code, _, err = run_cli(capsys, [T, files["mot"], "--model", "multi-pf", "--drop-frames",
                                    "3-99999999999", "--out", tmp_path, "--quiet",
                                    "--no-video"])
    assert code == 0, err
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["dropped_frames"] == list(range(3, N_FRAMES + 1))


# -- 14: standard error closed ---------------------------------------------------------------
@pytest.mark.parametrize("closed", ["2>&-", ">&- 2>&-"])
def test_track_with_stderr_closed(files, tmp_path, closed):
    """No ``--quiet``: the progress bar has nowhere to go, which is no error."""
    out = tmp_path / "out"
    cmd = (f"{sys.executable} -m pgm.app.cli track {files['seq']} --init 10,10,20,20 "
           f"--out {out} --no-video {closed}")
    proc = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True)
    assert proc.returncode == 0
    assert len((out / "tracks.txt").read_text().splitlines()) == N_FRAMES
    assert json.loads((out / "run.json").read_text())["complete"] is True


# -- 14, 18: pgm view on a crafted record ------------------------------------------------------
@pytest.fixture(scope="module")
def recorded(files, tmp_path_factory):
    """A --record run of the demo scene (and its record, for copies to be spoilt)."""
    run = tmp_path_factory.mktemp("rec") / "run"
    assert main([T, str(files["seq"]), "--model", "colour-pf", "--record", "--out", str(run),
                 "--quiet", "--no-video"]) == 0
    return run


def _spoilt(recorded, tmp_path, edit):
    """A copy of the recorded run whose record.jsonl lines are ``edit(lines)``."""
    run = tmp_path / "run"
    shutil.copytree(recorded, run, symlinks=True)
    path = run / "record" / "record.jsonl"
    lines = [json.loads(ln) for ln in path.read_text().splitlines()]
    path.write_text("".join(ln if isinstance(ln, str) else json.dumps(ln) + "\n"
                            for ln in edit(lines)))
    return run


def _set(field, value, line=0):
    def edit(lines):
        lines[line][field] = value
        return lines
    return edit


VIEW_CASES = [
    ("lines that are not objects", lambda lines: ["[1, 2]\n", "3\n"],
     ["record.jsonl line 1", "not a JSON object"]),
    ("NaN frame number", lambda lines: ['{"frame": NaN, "image": null}\n'],
     ["record.jsonl line 1", "'frame'"]),
    ("frame number a string", _set("frame", "one", line=1), ["line 2", "'frame'"]),
    ("variables a list", _set("variables", [1, 2]), ["line 1", "'variables'"]),
    ("messages not objects", _set("messages", [5]), ["line 1", "message"]),
    ("image ../", _set("image", "../../secret.jpg"), ["line 1", "../../secret.jpg"]),
    ("image absolute", _set("image", "/etc/hostname"), ["line 1", "/etc/hostname"]),
    ("image not a string", _set("image", 7), ["line 1", "'image'"]),
]


@pytest.mark.parametrize("case, edit, needles", VIEW_CASES, ids=[c[0] for c in VIEW_CASES])
def test_view_of_a_crafted_record(recorded, tmp_path, capsys, case, edit, needles):
    run = _spoilt(recorded, tmp_path, edit)
    code, _, err = run_cli(capsys, ["view", run])
    assert_names_the_input(code, err, *needles)
    assert not (run / "view.html").exists()


def test_view_embeds_no_file_outside_the_record(recorded, tmp_path, capsys):
    """A record naming ``../../secret.jpg`` is refused: the page never carries it."""
    secret = tmp_path / "secret.jpg"
    shutil.copy(next((recorded / "record" / "frames").iterdir()), secret)
    run = _spoilt(recorded, tmp_path, _set("image", "../../secret.jpg"))
    assert (run / "record" / "../../secret.jpg").resolve() == secret.resolve()
    code, _, _ = run_cli(capsys, ["view", run])
    assert code == 2 and not (run / "view.html").exists()


def test_view_refuses_a_thumbnail_that_links_out_of_the_record(recorded, tmp_path, capsys):
    """Where a name resolves is checked too: a thumbnail that is a symbolic link to a file
    outside the record, or a ``frames`` folder that links elsewhere, is refused in one
    line and the page is not written."""
    secret = tmp_path / "secret.jpg"
    shutil.copy(next((recorded / "record" / "frames").iterdir()), secret)
    run = tmp_path / "run"
    shutil.copytree(recorded, run)
    first = sorted((run / "record" / "frames").iterdir())[0]
    first.unlink()
    first.symlink_to(secret)
    code, _, err = run_cli(capsys, ["view", run])
    assert_names_the_input(code, err, "line 1", first.name, "outside")
    assert not (run / "view.html").exists()
    linked = tmp_path / "linked"
    shutil.copytree(recorded, linked)
    elsewhere = tmp_path / "data" / "thumbs"
    shutil.move(str(linked / "record" / "frames"), elsewhere)
    (linked / "record" / "frames").symlink_to(elsewhere, target_is_directory=True)
    code, _, err = run_cli(capsys, ["view", linked])
    assert_names_the_input(code, err, "outside")
    assert not (linked / "view.html").exists()


# -- 15: silently wrong -------------------------------------------------------------------------
def test_learn_gpdm_max_iter_is_a_cap(tmp_path, capsys):
    """``--max-iter 1`` runs one L-BFGS iteration (it ran a round of 10)."""
    pytest.importorskip("torch")
    from pgm.dynamics.gpdm import load_gpdm

    seqs = []
    for name, people in (("A", 2), ("B", 1)):
        folder = tmp_path / name
        (folder / "gt").mkdir(parents=True)
        (folder / "seqinfo.ini").write_text(f"[Sequence]\nname={name}\nframeRate=25\n"
                                            f"seqLength=14\n")
        jitter = np.random.default_rng(people).normal(0, 2, (people, 15, 2))
        rows = [f"{f},{k + 1},{10 + 3 * f + 50 * k + jitter[k, f, 0]:.2f},"
                f"{100 + jitter[k, f, 1]:.2f},20,50,1,1,1"
                for k in range(people) for f in range(1, 15)]
        (folder / "gt" / "gt.txt").write_text("\n".join(rows) + "\n")
        seqs.append(folder)
    for cap in (1, 3, 13):
        out = tmp_path / f"m{cap}.npz"
        code, stdout, err = run_cli(capsys, ["learn", "gpdm", "--train", *seqs, "--out", out,
                                             "--max-iter", cap])
        assert code == 0, err
        assert load_gpdm(out).info["iterations"] <= cap


def test_bench_reruns_a_run_whose_tracks_were_deleted(files, tmp_path, capsys):
    from pgm.app import experiment as exp

    toml = tmp_path / "e.toml"
    toml.write_text(f'seeds = 2\nmax_frames = 3\nsequences = ["{files["seq"]}"]\n'
                    f'[[models]]\nname = "colour-pf"\nparticles = 20\n')
    e = exp.load_experiment(toml)
    out = tmp_path / "out"
    assert len(exp.run_experiment(e, out).ran) == 2
    runs = exp.expand(e)
    (runs[0].folder(out) / "tracks.txt").unlink()
    assert exp.run_state(runs[0], out) == "incomplete"
    result = exp.run_experiment(e, out)
    assert [r.label for r in result.ran] == [runs[0].label]
    assert (runs[0].folder(out) / "tracks.txt").is_file()
    # and a run that lost its results is never a row of results.csv
    (runs[1].folder(out) / "tracks.txt").unlink()
    assert [row["seed"] for row in exp.collect_rows(runs, out)] == [runs[0].seed]


def test_model_file_with_a_fractional_dim_is_refused():
    from pgm.core.graph import FactorGraph

    decl = {"format": "pgm-factor-graph", "version": 1, "name": "x", "meta": {},
            "variables": [{"name": "object", "dim": 4.5}],
            "factors": [{"type": "GaussianPrior", "name": "prior", "kind": "prior",
                         "variables": ["object"],
                         "params": {"mean": [1, 2, 3, 4], "cov": 0.0}}]}
    with pytest.raises(ValueError, match="dim"):
        FactorGraph.from_dict(decl)


# -- 16: a plain run after a --record run leaves no stale page -----------------------------------
def test_plain_run_removes_the_earlier_view(files, tmp_path, capsys):
    out = tmp_path / "run"
    assert run_cli(capsys, [T, files["seq"], "--model", "colour-pf", "--record", "--out", out,
                            "--quiet", "--no-video"])[0] == 0
    assert run_cli(capsys, ["view", out])[0] == 0 and (out / "view.html").is_file()
    assert run_cli(capsys, [T, files["seq"], "--model", "colour-pf", "--out", out, "--quiet",
                            "--no-video"])[0] == 0
    assert not (out / "view.html").exists()


# -- 17: a FIFO as the video -----------------------------------------------------------------
def test_fifo_is_refused_not_waited_on(files, tmp_path):
    """FFmpeg would block opening a pipe with no writer, in native code where neither
    SIGINT nor SIGTERM reaches it; it is refused first. (The subprocess's timeout only
    guards the suite against the hang coming back.)"""
    fifo = tmp_path / "video.mp4"
    os.mkfifo(fifo)
    proc = subprocess.run([sys.executable, "-m", "pgm.app.cli", "track", str(fifo), "--init",
                           "1,1,5,5", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 2
    assert "named pipe" in proc.stderr and str(fifo) in proc.stderr
    assert "Traceback" not in proc.stderr


# -- API: ValueError, naming the argument ----------------------------------------------------
@pytest.fixture(scope="module")
def graph(files):
    from pgm.io.annotations import load_single_gt
    from pgm.models import colour_pf

    x, y, w, h = load_single_gt(files["seq"] / "groundtruth_rect.txt").boxes[0]
    return colour_pf.build_graph(colour_pf.Params(init_box=(x + w / 2, y + h / 2, w, h),
                                                  num_particles=20))


def _image():
    return np.zeros((240, 320, 3), np.uint8)


API_CASES = [
    ("gt=5", lambda seq, g: dict(source=seq, graph=g, gt=5), "gt"),
    ("source=[1, 2]", lambda seq, g: dict(source=[1, 2], graph=g), "source"),
    ("graph='x'", lambda seq, g: dict(source=seq, graph="x"), "graph"),
    ("frames [image, image]", lambda seq, g: dict(source=[_image(), _image()], graph=g),
     "source"),
    ("max_frames=0", lambda seq, g: dict(source=seq, graph=g, max_frames=0), "max_frames"),
    ("max_frames=-1", lambda seq, g: dict(source=seq, graph=g, max_frames=-1), "max_frames"),
]


@pytest.mark.parametrize("case, kwargs, needle", API_CASES, ids=[c[0] for c in API_CASES])
def test_track_api_bad_arguments(files, graph, case, kwargs, needle):
    from pgm.app.runner import track

    kw = kwargs(str(files["seq"]), graph)
    with pytest.raises(ValueError, match=needle):
        track(kw.pop("source"), kw.pop("graph"), rng=0, write_video=False, progress=False,
              **kw)


@pytest.mark.parametrize("decl", ["garbage", 5, None, [],
                                  {"format": "pgm-factor-graph", "version": 1, "name": "x",
                                   "meta": {}, "variables": [{"name": "o", "dim": 4}],
                                   "factors": [5]}])
def test_factor_graph_from_bad_declarations(decl):
    from pgm.core.graph import FactorGraph

    with pytest.raises(ValueError):
        FactorGraph.from_dict(decl)


def test_learn_gpdm_on_trajectories_that_do_not_vary(tmp_path, capsys):
    """Walkers that all move alike, frame after frame: nothing to learn, said in one line
    naming --train (it was an internal Cholesky error)."""
    pytest.importorskip("torch")
    folder = tmp_path / "A"
    (folder / "gt").mkdir(parents=True)
    (folder / "seqinfo.ini").write_text("[Sequence]\nname=A\nframeRate=25\nseqLength=14\n")
    rows = [f"{f},{k + 1},{10 + 3 * f + 50 * k},100,20,50,1,1,1"
            for k in range(2) for f in range(1, 15)]
    (folder / "gt" / "gt.txt").write_text("\n".join(rows) + "\n")
    code, _, err = run_cli(capsys, ["learn", "gpdm", "--train", folder, "--out",
                                    tmp_path / "m.npz", "--max-iter", "1"])
    assert_names_the_input(code, err, "--train", "do not vary")


def test_run_json_names_a_stream_url_as_given():
    """Issue 26, item 9: ``Path`` collapses ``//``; the URL is recorded as given."""
    from pathlib import Path

    from pgm.app.runner import source_text
    from pgm.io.video import LiveSource

    live = object.__new__(LiveSource)
    live.spec, live.path = "http://host/s.ts", Path("http://host/s.ts")
    assert source_text(live) == "http://host/s.ts"

    class Folder:
        path = Path("/data/seq")

    assert source_text(Folder()) == "/data/seq"
