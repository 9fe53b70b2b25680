"""``pgm eval --gt-dir --pred-dir``: every sequence of a folder, missing predictions, the
combined and mean rows, and the errors."""

import json

import pytest
from cli_run import run_cli

from pgm.core.errors import InputError
from pgm.evaluation.folders import evaluate_mot_folders


def _rows(n_frames, ids, id_offset=0):
    """MOT rows of walkers: ``id`` moves right from ``x = 40 * id`` at 3 px/frame."""
    return [f"{f},{i + id_offset},{40 * i + 3 * f},{50 + 7 * i},30,80,1,-1,-1,-1"
            for f in range(1, n_frames + 1) for i in ids]


@pytest.fixture
def folders(tmp_path):
    """GT: ``A/`` (MOTChallenge folder, two walkers in frames 1-10, seqLength 12) and
    ``B.txt`` (one walker, frames 1-5). PRED: ``A.txt`` exact (other identities),
    ``C.txt`` (no ground truth); B has no prediction."""
    gt, pred = tmp_path / "gt", tmp_path / "pred"
    (gt / "A" / "gt").mkdir(parents=True)
    (gt / "A" / "seqinfo.ini").write_text("[Sequence]\nname=A\nseqLength=12\n")
    (gt / "A" / "gt" / "gt.txt").write_text("\n".join(_rows(10, (1, 2))) + "\n")
    (gt / "B.txt").write_text("\n".join(_rows(5, (1,))) + "\n")
    (gt / "notes").mkdir()  # a folder without gt/gt.txt is passed over
    pred.mkdir()
    (pred / "A.txt").write_text("\n".join(_rows(10, (1, 2), id_offset=10)) + "\n")
    (pred / "C.txt").write_text("\n".join(_rows(3, (1,))) + "\n")
    return gt, pred


def test_only_the_predicted_sequences_are_scored_by_default(folders):
    """B has no prediction file: it is listed, and left out of every row."""
    res = evaluate_mot_folders(*folders)
    assert list(res["sequences"]) == ["A"] and res["missing"] == ["B"]
    assert not res["all_sequences"]
    for row in (res["combined"], res["mean"]):
        assert (row["mota"], row["idf1"], row["num_frames"]) == (1.0, 1.0, 12)


def test_hand_checked_numbers(folders):
    res = evaluate_mot_folders(*folders, all_sequences=True)
    a, b = res["sequences"]["A"], res["sequences"]["B"]
    assert list(res["sequences"]) == ["A", "B"]
    assert res["missing"] == ["B"] and res["unmatched"] == ["C"]
    assert (a["mota"], a["idf1"], a["hota"], a["num_frames"]) == (1.0, 1.0, 1.0, 12)
    assert (b["mota"], b["fn"], b["num_frames"], b["ospa_50_1"]) == (0.0, 5, 5, 50.0)
    c = res["combined"]
    # pooled counts: 25 ground-truth boxes, 5 missed, nothing else wrong
    assert (c["num_gt"], c["num_pred"], c["fn"], c["fp"], c["num_frames"]) == (25, 20, 5, 0, 17)
    assert c["mota"] == pytest.approx(1 - 5 / 25)
    assert c["idf1"] == pytest.approx(2 * 20 / (25 + 20))
    # OSPA over all 17 frames: 0 in A's 12, the cut-off 50 in B's 5
    assert c["ospa_50_1"] == pytest.approx(5 * 50 / 17)
    assert c["ospa2"] == pytest.approx((12 * a["ospa2"] + 5 * b["ospa2"]) / 17)
    m = res["mean"]
    assert m["mota"] == pytest.approx(0.5) and m["ospa_50_1"] == pytest.approx(25.0)
    assert "per_frame" not in a
    json.dumps(res, allow_nan=False)


def test_combined_equals_the_sequences_when_all_are_perfect(folders):
    gt, pred = folders
    (pred / "B.txt").write_text("\n".join(_rows(5, (1,), id_offset=3)) + "\n")
    res = evaluate_mot_folders(gt, pred)
    assert res["missing"] == []
    for key in ("mota", "idf1", "hota", "motp"):
        assert res["combined"][key] == pytest.approx(1.0), key
    assert res["combined"]["id_switches"] == 0  # identities never meet across sequences



def test_cli_table_and_json(folders, capsys):
    gt, pred = folders
    code, out, err = run_cli(capsys, "eval", "--gt-dir", gt, "--pred-dir", pred)
    assert code == 0, err
    assert "| B |" not in out and any(ln.startswith("| COMBINED | 1.000 |")
                                      for ln in out.splitlines())
    assert "no prediction file (not scored; --all-sequences scores them as empty): B" in out
    code, out, err = run_cli(capsys, "eval", "--gt-dir", gt, "--pred-dir", pred,
                             "--all-sequences")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("| sequence | MOTA")
    assert any(ln.startswith("| A | 1.000 |") for ln in lines)
    assert any(ln.startswith("| B | 0.000 |") for ln in lines)
    assert any(ln.startswith("| COMBINED | 0.800 |") for ln in lines)
    assert any(ln.startswith("| MEAN | 0.500 |") for ln in lines)
    assert "COMBINED: all sequences scored as one" in out
    assert "no prediction file (scored as empty): B" in out
    assert "prediction files without ground truth (not scored): C" in out
    code, out, _ = run_cli(capsys, "eval", "--gt-dir", gt, "--pred-dir", pred, "--json",
                           "--all-sequences")
    assert code == 0
    data = json.loads(out)
    assert data["combined"]["mota"] == pytest.approx(0.8) and data["missing"] == ["B"]
    # the one-file form is unchanged (scalars only)
    code, out, _ = run_cli(capsys, "eval", "--gt", gt / "A" / "gt" / "gt.txt", "--pred",
                           pred / "A.txt", "--json")
    assert code == 0
    one = json.loads(out)
    assert one["mota"] == 1.0 and "per_frame" not in one


@pytest.mark.parametrize("argv, needle", [
    (["--gt-dir", "{gt}", "--pred", "{pred}/A.txt"], "cannot be combined"),
    (["--gt", "{gt}/B.txt", "--pred-dir", "{pred}"], "cannot be combined"),
    (["--gt-dir", "{gt}"], "--gt-dir needs --pred-dir"),
    (["--pred-dir", "{pred}"], "--pred-dir needs --gt-dir"),
    (["--gt", "{gt}/B.txt"], "missing --pred"),
    ([], "missing --gt and --pred"),
    (["--gt-dir", "{gt}/nowhere", "--pred-dir", "{pred}"], "no such folder"),
    (["--gt-dir", "{gt}/B.txt", "--pred-dir", "{pred}"], "is not a folder"),
    (["--gt-dir", "{gt}/notes", "--pred-dir", "{pred}"], "holds no ground truth"),
    (["--gt-dir", "{gt}", "--pred-dir", "{gt}/notes"], "holds no <SEQ>.txt"),
])
def test_cli_errors_are_one_line(folders, capsys, argv, needle):
    gt, pred = folders
    args = [a.format(gt=gt, pred=pred) for a in argv]
    code, _, err = run_cli(capsys, "eval", *args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pgm: error: ") and needle in lines[0], err


def test_a_malformed_prediction_names_its_file(folders):
    gt, pred = folders
    (pred / "A.txt").write_text("1,1,10,10,30,80,1,-1,-1,-1\n1,1,50,10,30,80,1,-1,-1,-1\n")
    with pytest.raises(InputError, match=r"two boxes in frame 1 of .*A\.txt"):
        evaluate_mot_folders(gt, pred)
