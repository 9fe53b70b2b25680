"""The typed diagnostics of a step record: fields named where they are defined, read
also as mappings; a plate's report in ``record.plate``; per-replica fields follow the
replicas through births and deaths; a hook sees them."""

from __future__ import annotations

import numpy as np
import pytest

from pgm.core.frame import FrameContext
from pgm.inference import Engine
from pgm.inference.info import (
    AssociationInfo,
    PlateInfo,
    VariableInfo,
    VBInfo,
    realigned,
)
from pgm.inference.record import StepRecord
from pgm.models import sort as sort_model
from pgm.observation.detections import Detections


def test_info_reads_as_a_mapping_of_what_was_reported():
    info = VBInfo(iterations=3, elbo=[-2.0, -1.5])
    assert dict(info) == {"iterations": 3, "elbo": [-2.0, -1.5]}
    assert info["elbo"] is info.elbo and info.get("r_hat") is None and "r_hat" not in info
    with pytest.raises(KeyError):
        info["r_hat"]
    assert not VBInfo() and len(info) == 2


def test_merge_sets_declared_fields_and_keeps_the_rest_in_extra_where_there_is_one():
    v = VariableInfo(ess=10.0).merge(VariableInfo(resampled=True)).merge({"mine": 1})
    assert (v.ess, v.resampled, v.extra) == (10.0, True, {"mine": 1}) and v["mine"] == 1
    with pytest.raises(ValueError, match="VBInfo has no field 'mine'"):
        VBInfo().merge({"mine": 1})


def test_realigned_follows_the_surviving_replicas_and_pads_births():
    keep = np.array([True, False, True])
    v = VariableInfo(ess=np.array([1.0, 2.0, 3.0]), resampled=np.array([True, False, True]),
                     degenerate=np.array([1, 2]))
    realigned(v, keep, births=1)
    np.testing.assert_array_equal(v.ess, [1.0, 3.0, np.nan])
    np.testing.assert_array_equal(v.resampled, [True, True, False])
    np.testing.assert_array_equal(v.degenerate, [1])  # replica 2 is now replica 1
    d = realigned({"matched": np.array([0.0, 1.0, np.nan])}, keep, 0)
    np.testing.assert_array_equal(d["matched"], [0.0, np.nan])


def test_record_collects_a_variables_reports():
    rec = StepRecord(frame=1)
    rec.report("x", {"ess": 5.0})
    rec.report("x", VariableInfo(resampled=False))
    rec.report("x", None)
    assert isinstance(rec.info["x"], VariableInfo) and dict(rec.info["x"]) == {
        "ess": 5.0, "resampled": False}
    assert rec.plate is None and rec.plate_info() is rec.plate_info()


def test_a_sort_run_reports_typed_info_that_hooks_see():
    g = sort_model.build_graph(sort_model.Params())
    eng = Engine(g, np.random.default_rng(0))
    seen = []
    eng.add_hook("estimate", lambda e, stage, frame, rec: seen.append(type(rec.plate)))
    boxes = np.array([[100.0, 100, 40, 80], [300, 120, 40, 90]])
    for t in range(1, 6):
        dets = Detections(boxes + [3.0 * t, 0, 0, 0], np.ones(2))
        rec = eng.step(FrameContext(t, None, detections=dets))
    assert isinstance(rec.plate, PlateInfo)
    assert rec.plate.ids.shape == (2,) and rec.plate.reported.all() and rec.plate.births == 0
    assoc = [v for v in rec.info.values() if isinstance(v, AssociationInfo)]
    assert len(assoc) == 1 and np.isfinite(assoc[0].matched).all()
    assert seen and all(t in (PlateInfo, type(None)) for t in seen)
