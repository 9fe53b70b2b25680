"""The peer trackers run in their own venv (.venv-peers) and come back as toolkit data."""

import sys
from pathlib import Path

import numpy as np
import pytest

from pgm.core.boxes import iou_xywh
from pgm.io.annotations import MotTable, load_single_gt
from pgm.io.video import open_source

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _peers import SETUP_HINT, frame_paths, peer_python, run_mot_peers, run_sot_peers  # noqa: E402

pytestmark = [
    pytest.mark.data,
    pytest.mark.skipif(peer_python() is None, reason=SETUP_HINT),
]


def test_sot_peers_on_crossing(shared_data):
    src = open_source(shared_data / "Crossing")
    gt = load_single_gt(src.gt_path).until(15)
    paths = frame_paths(src, 1, 16)
    init = gt.boxes[0]
    res = run_sot_peers(paths, init)
    assert set(res) == {"csrt", "kcf", "mil"}
    for name, r in res.items():
        assert "error" not in r, (name, r)
        assert r["boxes"].shape == (15, 4)
        assert np.all(np.isfinite(r["boxes"]))
    csrt = res["csrt"]["boxes"]
    assert iou_xywh(csrt[:1], init[None, :])[0] == pytest.approx(1.0)
    ious = iou_xywh(gt.boxes, csrt[gt.frames - 1])
    assert ious.mean() > 0.3


def test_mot_peers_on_tud_campus(shared_data, tmp_path):
    res = run_mot_peers(shared_data / "TUD-Campus", last_frame=20, workdir=tmp_path)
    assert set(res) == {"sort", "bytetrack", "ocsort"}
    for name, r in res.items():
        assert "error" not in r, (name, r)
        table = r["table"]
        assert isinstance(table, MotTable)
        assert len(table) > 0
        assert table.frames.min() >= 1 and table.frames.max() <= 20
        assert r["path"] == tmp_path / f"{name}.txt"
        assert r["fps"] > 0
