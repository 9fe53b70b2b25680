"""``pgm bench``: the grid and its seeds, the local and Dask backends giving one table,
interruption and resumption, the command line, and every bad input.

The experiments are tiny (3 sequences × 3 models × 3 seeds, 5 frames, 20 particles) on
synthetic OTB folders, so they run everywhere; the shipped example runs on
``../shared/data`` (skipped where it is absent).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from pgm.app import experiment as exp
from pgm.app.cli import main
from pgm.core.errors import InputError, Interrupted
from pgm.synthetic import demo_scene

EXAMPLE = Path(__file__).resolve().parents[3] / "docs" / "experiments" / "example.toml"

TOML = """
name = "tiny"
root_seed = 7
seeds = 3
max_frames = 5
sequences = ["seqs/*"]

[[models]]
name = "colour-pf"
particles = 20

[[models]]
name = "part-graph"
label = "parts2"
parts = 2
particles = 20

[[models]]
name = "single-object"
particles = 20
scale-noise = 0.005
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    """Three 6-frame synthetic OTB sequences and the experiment file beside them."""
    root = tmp_path_factory.mktemp("experiment")
    for k, name in enumerate(("seqA", "seqB", "seqC")):
        demo_scene(seed=k, n_frames=6).write_otb(root / "seqs" / name)
    (root / "tiny.toml").write_text(TOML)
    return root / "tiny.toml"


@pytest.fixture(scope="module")
def reference(tiny, tmp_path_factory) -> Path:
    """The tiny experiment run uninterrupted with ``--jobs 2``: its folder."""
    out = tmp_path_factory.mktemp("reference")
    result = exp.run_experiment(exp.load_experiment(tiny), out, jobs=2)
    assert len(result.ran) == 27 and not result.failed and len(result.rows) == 27
    return out


def table(folder: Path) -> list[dict[str, str]]:
    """``results.csv`` without its timing columns."""
    with open(folder / "results.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return [{k: v for k, v in r.items() if not exp.is_timing_column(k)} for r in rows]


# -- the grid and its seeds --------------------------------------------------------------------
def test_grid_order_and_seeds_do_not_depend_on_order_or_subset(tiny):
    e = exp.load_experiment(tiny)
    runs = exp.expand(e)
    assert [s.name for s in e.sequences] == ["seqA", "seqB", "seqC"]
    assert [m.label for m in e.models] == ["colour-pf", "parts2", "single-object"]
    assert [r.label for r in runs[:4]] == ["seqA/colour-pf/0", "seqA/colour-pf/1",
                                           "seqA/colour-pf/2", "seqA/parts2/0"]
    assert len(runs) == e.n_runs == 27 and len({r.seed_int for r in runs}) == 27
    assert runs[5].argv("OUT")[:3] == ["track", runs[5].source, "--model"]
    assert "--particles=20" in runs[5].argv("OUT") and "--no-video" in runs[5].argv("OUT")
    # the seed is SeedSequence(root).spawn along (seed, sequence, model)
    r = runs[14]  # seqB / parts2 / seed 2
    assert r.spawn_key == (2, 1, 1)
    nested = (np.random.SeedSequence(7).spawn(3)[2].spawn(2)[1].spawn(2)[1])
    np.testing.assert_array_equal(nested.generate_state(2, np.uint32),
                                  exp.run_seed_sequence(7, 2, 1, 1).generate_state(2, np.uint32))
    by_label = {r.label: r.seed_int for r in runs}
    # a subset of the seeds, in another order, or more of them: the same seeds per run
    for seeds in ((2, 0), (0, 1, 2, 3), (1,)):
        for run in exp.expand(dataclasses.replace(e, seeds=seeds)):
            if run.label in by_label:
                assert run.seed_int == by_label[run.label], run.label
    # a model appended: the runs already there keep their seeds
    more = dataclasses.replace(e, models=e.models + (dataclasses.replace(e.models[0],
                                                                          label="extra"),))
    assert {r.label: r.seed_int for r in exp.expand(more) if r.model != "extra"} == by_label
    # a different root seed: different seeds
    other = exp.expand(dataclasses.replace(e, root_seed=8))
    assert all(a.seed_int != b.seed_int for a, b in zip(runs, other, strict=True))


# -- backends: one table ------------------------------------------------------------------------
@pytest.mark.slow
def test_jobs_2_writes_every_run_and_the_tables(reference):
    rows = table(reference)
    assert [(r["sequence"], r["model"], r["seed"]) for r in rows[:3]] == [
        ("seqA", "colour-pf", "0"), ("seqA", "colour-pf", "1"), ("seqA", "colour-pf", "2")]
    assert len(rows) == 27 and all(r["n_frames"] == "5" for r in rows)
    assert all(0.0 <= float(r["success_auc"]) <= 1.0 for r in rows)
    with open(reference / "results.csv", newline="") as fh:
        assert all(float(r["fps"]) > 0 for r in csv.DictReader(fh))
    run = reference / "runs" / "seqB" / "parts2" / "1"
    assert json.loads((run / "run.json").read_text())["complete"] is True
    assert {"tracks.txt", "metrics.json", "model.json", "task.json"} <= {
        p.name for p in run.iterdir()}
    assert not (run / "annotated.mp4").exists()  # write_video defaults to false
    task = json.loads((run / "task.json").read_text())
    assert task["command"].startswith("pgm track ") and "--seed " in task["command"]
    # seeds differ, so the runs of one (sequence, model) differ
    iou = [r["mean_iou"] for r in rows if r["sequence"] == "seqA" and r["model"] == "parts2"]
    assert len(set(iou)) > 1
    md = (reference / "results.md").read_text()
    assert "## seqC" in md and "| metric | colour-pf | parts2 | single-object |" in md
    assert "±" in md and "standard deviation" in md
    with open(reference / "summary.csv", newline="") as fh:
        summary = list(csv.DictReader(fh))
    iou = [s for s in summary if (s["sequence"], s["model"], s["metric"])
           == ("seqA", "parts2", "mean_iou")]
    assert len(iou) == 1 and iou[0]["n"] == "3"
    assert float(iou[0]["min"]) <= float(iou[0]["mean"]) <= float(iou[0]["max"])


@pytest.mark.slow
def test_dask_cluster_gives_the_same_table(tiny, reference, tmp_path):
    try:
        import distributed
    except ImportError:
        reason = ("Dask distributed is not installed (pip install pgm-tracking[cluster]; "
                  "run.sh installs it)")
        if os.environ.get("CI", "").strip().lower() in {"1", "true", "yes", "on", "y", "t"}:
            pytest.fail(f"{reason}; CI must run the cluster test")
        pytest.skip(reason)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        result = exp.run_experiment(exp.load_experiment(tiny), tmp_path, backend="dask",
                                    address=cluster.scheduler_address)
    assert len(result.ran) == 27 and not result.failed
    assert table(tmp_path) == table(reference)


# -- interrupted and resumed -------------------------------------------------------------------
@pytest.mark.slow
def test_interrupted_experiment_resumes_and_loses_nothing(tiny, reference, tmp_path,
                                                          monkeypatch):
    from pgm.app import runner

    calls: list[str] = []
    real_task, real_step = exp.run_task, runner.Engine.step

    interrupt = [True]

    def counting(run, out):
        calls.append(run.label)
        if interrupt[0] and len(calls) == 4:  # SIGTERM on the third frame of the 4th run
            interrupt[0] = False
            frames = []

            def step(self, ctx):
                frames.append(ctx)
                if len(frames) == 3:
                    raise Interrupted(15)
                return real_step(self, ctx)

            monkeypatch.setattr(runner.Engine, "step", step)
            try:
                return real_task(run, out)
            finally:
                monkeypatch.setattr(runner.Engine, "step", real_step)
        return real_task(run, out)

    monkeypatch.setattr(exp, "run_task", counting)
    e = exp.load_experiment(tiny)
    with pytest.raises(KeyboardInterrupt):
        exp.run_experiment(e, tmp_path, jobs=1)
    stopped = json.loads((tmp_path / "runs" / "seqA" / "parts2" / "0" / "run.json").read_text())
    assert stopped["complete"] is False and stopped["stopped"] == "interrupted by SIGTERM"
    assert len(table(tmp_path)) == 3  # the tables hold what finished
    calls.clear()
    result = exp.run_experiment(e, tmp_path, jobs=1)
    assert len(calls) == 24 and calls[0] == "seqA/parts2/0" and len(result.skipped) == 3
    assert table(tmp_path) == table(reference)
    # a run deleted, one marked incomplete, one finished with other settings: only those run
    shutil.rmtree(tmp_path / "runs" / "seqB" / "colour-pf" / "2")
    status = tmp_path / "runs" / "seqC" / "single-object" / "0" / "run.json"
    status.write_text(status.read_text().replace('"complete": true', '"complete": false'))
    task = tmp_path / "runs" / "seqA" / "colour-pf" / "1" / "task.json"
    task.write_text(task.read_text().replace('"max_frames": 5', '"max_frames": 4'))
    calls.clear()
    result = exp.run_experiment(e, tmp_path, jobs=1)
    assert sorted(calls) == ["seqA/colour-pf/1", "seqB/colour-pf/2", "seqC/single-object/0"]
    assert len(result.skipped) == 24 and table(tmp_path) == table(reference)


# -- the command line --------------------------------------------------------------------------
@pytest.mark.slow
def test_cli_runs_the_example_and_then_skips_it(shared_data, tmp_path, capsys):
    out = tmp_path / "bench"
    assert main(["bench", str(EXAMPLE), "--out", str(out), "--jobs", "2"]) == 0
    captured = capsys.readouterr()
    lines = [ln for ln in captured.err.splitlines() if ln.startswith("[")]
    assert len(lines) == 27 and all(": complete in " in ln for ln in lines)
    assert "27 of 27 runs complete" in captured.out
    rows = table(out)
    assert {r["sequence"] for r in rows} == {"Crossing", "David", "Tiger1"}
    assert {r["model"] for r in rows} == {"colour-pf", "part-graph-2", "single-object"}
    assert len(rows) == 27 and (out / "results.md").is_file()
    assert (out / "experiment.toml").read_text() == EXAMPLE.read_text()
    assert main(["bench", str(EXAMPLE), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "(0 run now, 27 skipped)" in captured.out
    assert "27 complete, skipped; running 0" in captured.err
    assert main(["bench", str(EXAMPLE), "--out", str(out), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""  # --quiet: nothing but errors
    assert table(out) == rows


def test_failed_runs_are_listed_and_the_others_kept(tiny, tmp_path, capsys):
    """A run that fails at run time (here: a frame of another size) fails alone."""
    folder = tmp_path / "seqs"
    shutil.copytree(tiny.parent / "seqs" / "seqA", folder / "seqA")
    shutil.copytree(tiny.parent / "seqs" / "seqA", folder / "broken")
    frame = sorted((folder / "broken" / "img").iterdir())[1]
    cv2.imwrite(str(frame), np.zeros((20, 20, 3), np.uint8))
    toml = tmp_path / "e.toml"
    toml.write_text('seeds = 1\nmax_frames = 3\nsequences = ["seqs/*"]\n'
                    '[[models]]\nname = "colour-pf"\nparticles = 10\n')
    code = main(["bench", str(toml), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith("pgm: error: 1 of 2 runs failed (first: broken/colour-pf/0: ")
    assert "failures.txt" in err
    assert [r["sequence"] for r in table(tmp_path / "out")] == ["seqA"]
    assert (tmp_path / "out" / "failures.txt").read_text().startswith("broken/colour-pf/0: ")


def test_progress_bar_only_on_a_terminal(tiny, tmp_path, monkeypatch):
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    e = exp.load_experiment(tiny)
    e = dataclasses.replace(e, sequences=e.sequences[:1], models=e.models[:1], seeds=(0, 1),
                            max_frames=2)
    for tty, out in ((True, tmp_path / "a"), (False, tmp_path / "b")):
        stream = Terminal() if tty else io.StringIO()
        monkeypatch.setattr(sys, "stderr", stream)
        exp.run_experiment(e, out, progress=lambda line, s=stream: print(line, file=s))
        text = stream.getvalue()
        assert "[1/2] seqA/colour-pf/0: complete in" in text and "2 runs (1 sequence" in text
        assert ("run/s" in text) is tty


# -- bad input ---------------------------------------------------------------------------------
MODELS = '[[models]]\nname = "colour-pf"\n'
SEQS = 'sequences = ["seqs/seqA"]\n'


@pytest.mark.parametrize("text, needle", [
    ("sequences = [\n", "is not valid TOML"),
    ('colour = "red"\n' + SEQS + MODELS, "unknown key 'colour'"),
    (SEQS + '[[models]]\nname = "kalman-magic"\n', "unknown model 'kalman-magic'"),
    (SEQS + '[[models]]\nlabel = "x"\n', "name is missing"),
    (SEQS + MODELS + "particle = 10\n", "unknown option 'particle'; did you mean 'particles'"),
    (SEQS + MODELS + "particles = 0\n", "--particles must be a positive integer"),
    (SEQS + MODELS + 'camera-motion = "sideways"\n', "camera-motion must be one of"),
    (SEQS + MODELS + "show-particles = 1\n", "show-particles is a flag"),
    (SEQS + MODELS + "seed = 3\n", "'seed' is not a per-model option (set by root_seed"),
    (SEQS + MODELS + 'init = "1,1,5,5"\n', "'init' is not a per-model option"),
    (SEQS + '[[models]]\nname = "single-object"\nparts = 2\n', "--parts does not apply"),
    (SEQS + '[[models]]\nname = "colour-pf"\ndetector = "mog2"\n', "detector applies to"),
    (SEQS + MODELS + MODELS, "two models are labelled 'colour-pf'"),
    (SEQS + '[[models]]\nname = "colour-pf"\nlabel = "a/b"\n', "label must be"),
    (SEQS, "no models"),
    (MODELS, "no sequences"),
    ("sequences = []\n" + MODELS, "sequences is an empty list"),
    ('sequences = ["seqs/nothing*"]\n' + MODELS, "'seqs/nothing*' matches no sequence"),
    ('sequences = ["seqs/seqZ"]\n' + MODELS, "no such file or folder: 'seqs/seqZ'"),
    ('sequences = ["seqs/seqA", {path = "seqs/seqB", name = "seqA"}]\n' + MODELS,
     "two sequences are named 'seqA'"),
    ('sequences = ["plain"]\n' + MODELS, "has no ground truth, which the single-object"),
    (SEQS + '[[models]]\nname = "phd"\n', "has no det/det.txt"),
    ("seeds = 0\n" + SEQS + MODELS, "seeds must be a count >= 1"),
    ("seeds = -2\n" + SEQS + MODELS, "seeds must be a count >= 1"),
    ("seeds = [1, 1]\n" + SEQS + MODELS, "seed 1 is listed twice"),
    ("seeds = []\n" + SEQS + MODELS, "seeds is an empty list"),
    ('seeds = "3"\n' + SEQS + MODELS, "seeds must be a count >= 1 or a list"),
    ("seeds = [0, -1]\n" + SEQS + MODELS, "seeds must be integers >= 0"),
    ("seeds = true\n" + SEQS + MODELS, "seeds must be a count"),
    ("root_seed = -1\n" + SEQS + MODELS, "root_seed must be an integer >= 0"),
    ("max_frames = 0\n" + SEQS + MODELS, "max_frames must be an integer >= 1"),
    ('write_video = "yes"\n' + SEQS + MODELS, "write_video must be true or false"),
])
def test_bad_experiment_files_are_one_line_errors(tiny, tmp_path, capsys, text, needle):
    (tmp_path / "seqs").symlink_to(tiny.parent / "seqs")
    plain = tmp_path / "plain"
    plain.mkdir()
    shutil.copy(next((tiny.parent / "seqs" / "seqA" / "img").iterdir()), plain / "0001.png")
    toml = tmp_path / "bad.toml"
    toml.write_text(text)
    code = main(["bench", str(toml), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("pgm: error: ") and needle in lines[0], lines[0]
    assert not (tmp_path / "out" / "runs").exists()


@pytest.mark.parametrize("extra, needle", [
    (["--backend", "ray"], "the cluster backend is Dask distributed, not Ray"),
    (["--backend", "spark"], "--backend must be one of local, dask"),
    (["--address", "tcp://127.0.0.1:1"], "--address applies to --backend dask"),
])
def test_bad_command_lines(tiny, tmp_path, capsys, extra, needle):
    code = main(["bench", str(tiny), "--out", str(tmp_path / "out"), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and needle in err, err


def test_bad_jobs_is_refused_by_the_parser(tiny, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["bench", str(tiny), "--out", str(tmp_path), "--jobs", "0"])
    assert info.value.code == 2
    assert "--jobs must be a positive integer" in capsys.readouterr().err
    with pytest.raises(InputError, match="--jobs must be a positive integer"):
        exp.run_experiment(exp.load_experiment(tiny), tmp_path, jobs=0)


def test_missing_experiment_file_and_dask_not_installed(tiny, tmp_path, capsys, monkeypatch):
    assert main(["bench", str(tmp_path / "nope.toml"), "--out", str(tmp_path)]) == 2
    assert "no such experiment file" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    assert main(["bench", str(tiny), "--out", str(tmp_path / "o"), "--backend", "dask"]) == 2
    err = capsys.readouterr().err
    assert "pip install pgm-tracking[cluster]" in err and len(err.strip().splitlines()) == 1
    with pytest.raises(InputError, match="Dask distributed"):
        exp.run_experiment(exp.load_experiment(tiny), tmp_path / "o", backend="dask")
