"""``pgm learn gpdm``: end to end on a shared MOT sequence (model + latent-space plot),
and every bad input as one ``pgm: error:`` line with exit code 2."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_bad_input import assert_one_line_error, run_cli  # same folder: on sys.path

from pgm.app.cli import GPDM_HELP_DEFAULTS
from pgm.dynamics.gpdm import GPDMSettings, load_gpdm


def _mot_folder(root, name, people, *, frames=12, frame_rate="25"):
    """A MOT folder (seqinfo.ini + gt/gt.txt, no images) with ``people`` walkers."""
    folder = root / name
    (folder / "gt").mkdir(parents=True)
    info = "[Sequence]\nname=" + name + "\n"
    if frame_rate is not None:
        info += f"frameRate={frame_rate}\n"
    (folder / "seqinfo.ini").write_text(info + f"seqLength={frames}\n")
    rows = [f"{f},{k + 1},{10 + 3 * f + 50 * k},100,20,50,1,1,1"
            for k in range(people) for f in range(1, frames + 1)]
    (folder / "gt" / "gt.txt").write_text("\n".join(rows) + "\n")
    return folder


@pytest.mark.slow
def test_learn_gpdm_on_a_shared_sequence(shared_data, tmp_path, capsys):
    seq = shared_data / "TUD-Campus"
    if not (seq / "gt" / "gt.txt").is_file():
        pytest.skip(f"{seq}/gt/gt.txt not found")
    out, plot = tmp_path / "m" / "gpdm.npz", tmp_path / "m" / "latent.png"
    code, stdout, err = run_cli(capsys, ["learn", "gpdm", "--train", seq, "--out", out,
                                         "--plot", plot, "--max-iter", "1", "--latent-dim",
                                         "3", "--balanced", "--seed", "4"])
    assert code == 0, err
    lines = stdout.strip().splitlines()
    assert len(lines) == 1 and "one-step training RMSE" in lines[0] and str(out) in lines[0]
    model = load_gpdm(out)
    assert model.latent_dim == 3 and model.obs_dim == 3
    assert model.settings.balanced and not model.settings.mirror
    assert model.info["sources"] == ["TUD-Campus"] and model.lengths.size >= 2
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and plot.stat().st_size > 5000


def test_learn_gpdm_without_images_and_with_mirroring(tmp_path, capsys):
    """Training needs only seqinfo.ini and gt/gt.txt; --mirror doubles the sequences."""
    a = _mot_folder(tmp_path, "A", 2, frames=12)
    b = _mot_folder(tmp_path, "B", 1, frames=14, frame_rate="7")
    out = tmp_path / "m.npz"
    code, stdout, err = run_cli(capsys, ["learn", "gpdm", "--train", a, b, "--out", out,
                                         "--mirror", "--max-iter", "1"])
    assert code == 0, err
    model = load_gpdm(out)
    assert model.settings.mirror and model.lengths.tolist() == [11, 11, 11, 11, 13, 13]
    assert model.latent_dim == GPDMSettings().latent_dim
    # 7 fps: the walker's 3 px per frame at height 50 is 0.42 heights per second
    y = model.y_mean + model.y_std * model.Y
    np.testing.assert_allclose(np.abs(y[-13:, 0]), 3 / 50 * 7, rtol=1e-9)
    assert "3 trajectories of 2 sequence(s)" in stdout


def test_help_shows_defaults_and_an_example(capsys):
    code, stdout, _ = run_cli(capsys, ["learn", "gpdm", "--help"])
    assert code == 0
    assert "example:" in stdout and "pgm learn gpdm --train" in stdout
    defaults = GPDMSettings()
    assert GPDM_HELP_DEFAULTS == {k: getattr(defaults, k) for k in GPDM_HELP_DEFAULTS}
    assert set(GPDM_HELP_DEFAULTS) <= {f.name for f in dataclasses.fields(GPDMSettings)}
    assert f"(default: {defaults.max_iter})" in stdout
    assert f"(default: {defaults.latent_dim})" in stdout


@pytest.fixture
def bad(tmp_path):
    f = {"good": _mot_folder(tmp_path, "good", 2),
         "one": _mot_folder(tmp_path, "one", 1),
         "short": _mot_folder(tmp_path, "short", 3, frames=6),
         "no_rate": _mot_folder(tmp_path, "no_rate", 2, frame_rate=None),
         "bad_rate": _mot_folder(tmp_path, "bad_rate", 2, frame_rate="fast"),
         "no_gt": tmp_path / "no_gt", "a_file": tmp_path / "a_file.txt",
         "bad_gt": _mot_folder(tmp_path, "bad_gt", 2)}
    f["no_gt"].mkdir()
    (f["no_gt"] / "seqinfo.ini").write_text("[Sequence]\nframeRate=25\n")
    f["a_file"].write_text("x")
    (f["bad_gt"] / "gt" / "gt.txt").write_text("1,2,three\n")
    return f


CASES = [
    ("missing folder", ["--train", "{tmp}/nope", "--out", "{tmp}/m.npz"], "nope"),
    ("no gt", ["--train", "{no_gt}", "--out", "{tmp}/m.npz"], "gt/gt.txt"),
    ("a file as --train", ["--train", "{a_file}", "--out", "{tmp}/m.npz"], "a_file"),
    ("no frameRate", ["--train", "{no_rate}", "--out", "{tmp}/m.npz"], "frameRate"),
    ("bad frameRate", ["--train", "{bad_rate}", "--out", "{tmp}/m.npz"], "frameRate"),
    ("malformed gt", ["--train", "{bad_gt}", "--out", "{tmp}/m.npz"], "gt.txt"),
    ("one trajectory", ["--train", "{one}", "--out", "{tmp}/m.npz"], "at least 2"),
    ("too short", ["--train", "{short}", "--out", "{tmp}/m.npz"], "at least 2"),
    ("--out not .npz", ["--train", "{good}", "--out", "{tmp}/m.txt"], ".npz"),
    ("--out under a file", ["--train", "{good}", "--out", "{a_file}/m.npz"], "a_file"),
    ("--plot not an image", ["--train", "{good}", "--out", "{tmp}/m.npz", "--plot",
                             "{tmp}/p.jpg"], "--plot"),
    ("--max-iter negative", ["--train", "{good}", "--out", "{tmp}/m.npz", "--max-iter",
                             "-1"], "--max-iter"),
    ("--latent-dim 0", ["--train", "{good}", "--out", "{tmp}/m.npz", "--latent-dim", "0"],
     "--latent-dim"),
]


@pytest.mark.parametrize("case, template, needle", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line(bad, tmp_path, capsys, case, template, needle):
    argv = ["learn", "gpdm"] + [a.format(tmp=tmp_path, **bad) for a in template]
    code, _, err = run_cli(capsys, argv)
    assert_one_line_error(code, err, needle)
    assert not (tmp_path / "m.npz").exists()
