"""Issue 26, item 7: ``pgm report`` averages seeds of one configuration only; runs of
one sequence and model that differ in length or settings are separate rows."""

from __future__ import annotations

import json

import pytest

from pgm.app.cli import main
from pgm.app.report import group_runs, load_run
from pgm.synthetic import demo_scene


def _run(folder, frames, auc, particles=100, seq="/data/Crossing"):
    folder.mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps(
        {"complete": True, "model": "colour-pf", "source": seq, "frames": frames,
         "num_particles": {"object": particles}, "camera_motion": "off", "fps": 100.0}))
    (folder / "metrics.json").write_text(json.dumps(
        {"n_frames": frames, "success_auc": auc, "precision_at_20": auc}))
    return folder


def test_runs_of_other_lengths_are_not_averaged(tmp_path):
    runs = [load_run(_run(tmp_path / str(s), 300, 0.5 + s / 10), tmp_path) for s in (0, 1)]
    runs.append(load_run(_run(tmp_path / "2", 50, 0.9), tmp_path))
    groups = group_runs(runs)
    by_label = {g.label: len(g.runs) for g in groups}
    assert by_label == {"colour-pf (300 frames)": 2, "colour-pf (50 frames)": 1}


def test_runs_of_other_settings_are_not_averaged(tmp_path):
    runs = [load_run(_run(tmp_path / str(p), 100, 0.5, particles=p), tmp_path)
            for p in (50, 100)]
    assert sorted(g.label for g in group_runs(runs)) == ["colour-pf (particles 100)",
                                                         "colour-pf (particles 50)"]


def test_seeds_of_one_configuration_are_one_row(tmp_path):
    runs = [load_run(_run(tmp_path / str(s), 100, 0.4 + s / 10), tmp_path) for s in range(3)]
    groups = group_runs(runs)
    assert [(g.label, len(g.runs)) for g in groups] == [("colour-pf", 3)]


def test_report_of_a_300_and_a_50_frame_run(tmp_path, capsys):
    """The case of the issue, end to end: two 'pgm track' runs of one sequence, one cut
    short with --max-frames, then 'pgm report': two rows, each its own frame count (not
    "frames 175 ± 177"), and a warning naming the difference."""
    scene = tmp_path / "scene"
    demo_scene(seed=0, n_frames=8).write_otb(scene)
    for name, extra in (("full", []), ("short", ["--max-frames", "4"])):
        code = main(["track", str(scene), "--model", "colour-pf", "--particles", "20",
                     "--out", str(tmp_path / "runs" / name), "--quiet", "--no-video"] + extra)
        assert code == 0
    capsys.readouterr()
    assert main(["report", str(tmp_path / "runs")]) == 0
    err = capsys.readouterr().err
    assert "pgm: warning:" in err and "differ in frames" in err
    page = (tmp_path / "runs" / "report.html").read_text(encoding="utf-8")
    assert "colour-pf (8 frames)" in page and "colour-pf (4 frames)" in page
    summary = page.split('id="summary"')[1].split("</section>")[0]
    tables = "".join(t.split("</table>")[0] for t in summary.split("<table")[1:])
    assert tables and "±" not in tables  # one run per row: nothing averaged


@pytest.mark.parametrize("bad", ["[]", '{"meta": 5}', "{" * 10 + "}" * 10])
def test_an_unreadable_model_json_does_not_split(tmp_path, bad):
    runs = [load_run(_run(tmp_path / str(s), 100, 0.5), tmp_path) for s in range(2)]
    (runs[0].path / "model.json").write_text(bad)
    assert [len(g.runs) for g in group_runs(runs)] == [2]
