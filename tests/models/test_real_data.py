"""The colour particle filter and the part graphs on the shared real sequences (CLI).

Reference (Zhang and Kang 2015, a faithful one-node implementation): FaceOcc1 success AUC
about 0.75; on Crossing every fixed-size colour tracker stops near 0.5. Over 5 seeds
at 100 particles this implementation measured FaceOcc1 0.759–0.770 and Crossing
0.35–0.41 (see the closing note of issue 2); the floors below sit well under those
ranges, so they catch a broken tracker, not seed noise.
"""

import json

import pytest

from pgm.app.cli import main

pytestmark = [pytest.mark.data, pytest.mark.slow]


@pytest.mark.parametrize("sequence, floor_auc, floor_prec", [("FaceOcc1", 0.70, 0.70),
                                                             ("Crossing", 0.25, 0.55)])
def test_colour_pf_on_real_sequences(shared_data, tmp_path, capsys, sequence, floor_auc,
                                     floor_prec):
    seq = shared_data / sequence
    code = main(["track", str(seq), "--model", "colour-pf", "--out", str(tmp_path),
                 "--particles", "100", "--seed", "0", "--no-video", "--quiet"])
    assert code == 0, capsys.readouterr().err
    m = json.loads((tmp_path / "metrics.json").read_text())
    expected_frames = {"FaceOcc1": 178, "Crossing": 120}[sequence]
    assert m["n_frames"] == expected_frames and m["n_missing"] == 0
    assert m["success_auc"] > floor_auc
    assert m["precision_at_20"] > floor_prec


@pytest.mark.parametrize("parts, floor_auc", [(2, 0.74), (3, 0.76)])
def test_part_graph_on_faceocc1(shared_data, tmp_path, capsys, parts, floor_auc):
    """The paper's setting (``--preset paper``), measured over seeds 0-4 (issue 3 note): two
    nodes 0.787-0.812, three 0.802-0.810; the one-node filter at the paper's 30 particles
    0.750-0.772."""
    code = main(["track", str(shared_data / "FaceOcc1"), "--model", "part-graph", "--preset",
                 "paper", "--parts", str(parts), "--out", str(tmp_path), "--seed", "0",
                 "--no-video", "--quiet"])
    assert code == 0, capsys.readouterr().err
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["success_auc"] > floor_auc
