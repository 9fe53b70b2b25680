"""The step record: a variable's reports gathered into one typed info, the plate's own
report made once, and runtimes found in the order registered (the latest first)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pgm.inference.info import PlateInfo, VariableInfo
from pgm.inference.record import _RUNTIMES, StepRecord, register_runtime, runtime_for


def test_reports_of_a_variable_gather_in_its_variable_info():
    rec = StepRecord(frame=3)
    rec.report("x", VariableInfo(own_mass=0.4))
    rec.report("x", {"resampled": True, "note": "mine"})
    rec.report("y", {})
    info = rec.info["x"]
    assert isinstance(info, VariableInfo) and "y" not in rec.info
    assert (info.own_mass, info.resampled, info.extra) == (0.4, True, {"note": "mine"})


def test_the_plate_info_is_made_once():
    rec = StepRecord(frame=1)
    p = rec.plate_info()
    p.births = 2
    assert rec.plate is p and rec.plate_info().births == 2 and isinstance(p, PlateInfo)
    p.ids = np.array([1, 2])
    assert dict(p) == {"births": 2, "ids": p.ids}


def test_runtimes_are_asked_latest_first():
    class A:
        pass

    class B:
        pass

    g, other = SimpleNamespace(name="g", plates=[]), SimpleNamespace(name="o", plates=[])
    before = list(_RUNTIMES)
    try:
        register_runtime(lambda graph: graph.name == "g", A())
        register_runtime(lambda graph: graph.name == "g", B())
        assert isinstance(runtime_for(g), B) and runtime_for(other) is None
    finally:
        _RUNTIMES[:] = before
