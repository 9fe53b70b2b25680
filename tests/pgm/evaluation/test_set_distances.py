"""Set distances: OSPA, OSPA(2) and the cardinality error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pgm.core.errors import InputError
from pgm.evaluation.mot import (
    foot_points,
)
from pgm.evaluation.set_distances import cardinality_error, ospa, ospa2, ospa_components

# --------------------------------------------------------------------------- OSPA


def test_ospa_identical_sets_is_zero() -> None:
    X = np.array([[0.0, 0.0], [10.0, 5.0], [-3.0, 7.0]])
    for p in (1, 2):
        assert ospa(X, X, 50, p) == 0.0
        assert ospa(X, X[::-1], 50, p) == pytest.approx(0.0, abs=1e-12)


def test_ospa_empty_sets() -> None:
    X = np.array([[1.0, 2.0], [3.0, 4.0]])
    assert ospa(np.zeros((0, 2)), np.zeros((0, 2)), 50, 1) == 0.0
    assert ospa([], [], 50, 2) == 0.0
    assert ospa(X, np.zeros((0, 2)), 50, 1) == 50.0
    assert ospa([], X, 100, 2) == 100.0
    assert ospa_components(X, [], 50, 1) == (50.0, 0.0, 50.0)


def test_ospa_cardinality_term() -> None:
    # one point matched at distance 5, one unmatched point: (5 + c) / 2 with c = 10
    X = np.array([[0.0, 0.0]])
    Y = np.array([[3.0, 4.0], [100.0, 0.0]])
    d, loc, card = ospa_components(X, Y, 10, 1)
    assert d == pytest.approx(7.5)
    assert loc == pytest.approx(2.5)
    assert card == pytest.approx(5.0)
    assert ospa(Y, X, 10, 1) == pytest.approx(7.5)
    # the cut-off: the matched distance 5 is cut to 4
    assert ospa(X, Y, 4, 1) == pytest.approx((4 + 4) / 2)


def test_ospa_p2_by_hand() -> None:
    X = np.array([[0.0, 0.0], [10.0, 0.0]])
    Y = np.array([[10.0, 4.0], [0.0, 3.0]])  # optimal pairing: 3 and 4
    assert ospa(X, Y, 100, 2) == pytest.approx(math.sqrt((9 + 16) / 2))
    assert ospa(X, Y, 3.5, 2) == pytest.approx(math.sqrt((9 + 3.5**2) / 2))
    d, loc, card = ospa_components(X, Y[:1], 5, 2)   # 10 ↔ (10, 4): 4; one missing: c
    assert d == pytest.approx(math.sqrt((16 + 25) / 2))
    assert d**2 == pytest.approx(loc**2 + card**2)


def test_ospa_uses_the_optimal_assignment() -> None:
    X = np.array([[0.0], [1.0]])
    Y = np.array([[1.1], [0.1]])
    assert ospa(X, Y, 10, 1) == pytest.approx(0.1)


def test_ospa_rejects_bad_input() -> None:
    X = np.zeros((2, 2))
    with pytest.raises(InputError, match="cut-off"):
        ospa(X, X, 0, 1)
    with pytest.raises(InputError, match="order"):
        ospa(X, X, 10, 0.5)
    with pytest.raises(InputError, match="dimension"):
        ospa(X, np.zeros((2, 3)), 10, 1)
    with pytest.raises(InputError, match="shape"):
        ospa(np.zeros(2), X, 10, 1)
    with pytest.raises(InputError, match="non-finite"):
        ospa(np.array([[np.nan, 0.0]]), X, 10, 1)


_coord = st.floats(-60, 60, allow_nan=False, allow_infinity=False)
_set = st.lists(st.tuples(_coord, _coord), min_size=0, max_size=4).map(
    lambda pts: np.array(pts, dtype=float).reshape(-1, 2))


@settings(max_examples=150, deadline=None)
@given(_set, _set, _set, st.sampled_from([1.0, 2.0, 3.0]), st.sampled_from([5.0, 50.0]))
def test_ospa_is_a_metric(X: np.ndarray, Y: np.ndarray, Z: np.ndarray, p: float,
                          c: float) -> None:
    dxy, dyx = ospa(X, Y, c, p), ospa(Y, X, c, p)
    assert dxy == pytest.approx(dyx, abs=1e-9)
    assert 0.0 <= dxy <= c + 1e-9
    assert ospa(X, Z, c, p) <= dxy + ospa(Y, Z, c, p) + 1e-9
    comps = ospa_components(X, Y, c, p)
    assert comps.distance**p == pytest.approx(comps.localisation**p + comps.cardinality**p,
                                              abs=1e-9)


# --------------------------------------------------------------------------- OSPA(2)


def _track(frames: range, point: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    f = np.array(list(frames))
    return f, np.tile(np.array(point, dtype=float), (f.size, 1))


def test_ospa2_identical_tracks_is_zero() -> None:
    rng = np.random.default_rng(1)
    tracks = {i: (np.arange(i, i + 12), rng.normal(size=(12, 2)) * 30) for i in range(4)}
    res = ospa2(tracks, dict(tracks), 50, 1, 5)
    assert res.frames.tolist() == list(range(0, 15))
    assert np.all(res.values == 0.0)
    assert res.mean == 0.0


def test_ospa2_by_hand() -> None:
    # true A at (0, 0) in frames 1..10, true C far away in 8..10; estimate B at (3, 4)
    # (5 px from A) in frames 1..5 only. c = 50, p = 1.
    gt = {"A": _track(range(1, 11), (0.0, 0.0)), "C": _track(range(8, 11), (500.0, 500.0))}
    est = {"B": _track(range(1, 6), (3.0, 4.0))}
    res = ospa2(gt, est, 50, 1, 10, frames=range(1, 22))
    v = dict(zip(res.frames.tolist(), res.values.tolist(), strict=True))
    # window truncated at the start: frames 1..k
    for k in range(1, 6):
        assert v[k] == pytest.approx(5.0)
    assert v[6] == pytest.approx((5 * 5 + 50) / 6)
    assert v[7] == pytest.approx((5 * 5 + 2 * 50) / 7)
    # frame 10: d(A, B) = (5*5 + 5*50) / 10 = 27.5; C has no partner: (27.5 + 50) / 2
    assert v[10] == pytest.approx((27.5 + 50) / 2)
    # frame 12, window 3..12: d(A, B) = (3*5 + 5*50) / 8; d(C, B) = 50 (no common frame)
    assert v[12] == pytest.approx(((3 * 5 + 5 * 50) / 8 + 50) / 2)
    # frame 16, window 7..16: no estimated track left -> c; frame 21: both empty -> 0
    assert v[16] == 50.0
    assert v[21] == 0.0
    assert res.mean == pytest.approx(np.mean(res.values))
    # p = 2 at frame 10: sqrt((27.5^2 + 50^2) / 2)
    r2 = ospa2(gt, est, 50, 2, 10, frames=[10])
    assert r2.values[0] == pytest.approx(math.sqrt((27.5**2 + 50**2) / 2))


def test_ospa2_rejects_bad_input() -> None:
    gt = {1: _track(range(1, 4), (0.0, 0.0))}
    with pytest.raises(InputError, match="window"):
        ospa2(gt, gt, 50, 1, 0)
    with pytest.raises(InputError, match="twice"):
        ospa2({1: (np.array([1, 1]), np.zeros((2, 2)))}, gt, 50, 1)
    with pytest.raises(InputError, match="points"):
        ospa2({1: (np.array([1, 2]), np.zeros((3, 2)))}, gt, 50, 1)
    assert ospa2({}, {}, 50, 1).mean == 0.0


# --------------------------------------------------------------------------- cardinality


def test_cardinality_error() -> None:
    err = cardinality_error([3, 3, 0, 2], [3, 1, 1, 2])
    assert err.per_frame.tolist() == [0, -2, 1, 0]
    assert err.mean_abs == pytest.approx(0.75)
    with pytest.raises(InputError):
        cardinality_error([1, 2], [1])
    with pytest.raises(InputError):
        cardinality_error([-1], [1])


def test_foot_points() -> None:
    assert foot_points(np.array([[10.0, 20.0, 4.0, 30.0]])).tolist() == [[12.0, 50.0]]
