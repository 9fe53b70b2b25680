"""A run's track rows kept compactly: the table they make is the one the numbers make,
and they hold 56 bytes a row (at most twice that), not a Python list's ~320."""

import numpy as np

from pgm.io.annotations import MotTable, TrackRows


def test_track_rows_make_the_table_of_their_numbers():
    rng = np.random.default_rng(0)
    rows = TrackRows(capacity=3)  # grows several times
    want = {"f": [], "i": [], "b": [], "c": []}
    for frame in range(1, 60):
        k = int(rng.integers(0, 9))
        f, i = np.full(k, frame), rng.integers(1, 50, k)
        b, c = rng.normal(size=(k, 4)) * 100, rng.random(k)
        rows.extend(f, i, b, c)
        for key, v in zip("fibc", (f, i, b, c), strict=True):
            want[key].extend(v.tolist())
    got = rows.table()
    ref = MotTable(np.asarray(want["f"], dtype=np.int64), np.asarray(want["i"], dtype=np.int64),
                   np.asarray(want["b"], dtype=float).reshape(-1, 4),
                   np.asarray(want["c"], dtype=float))
    assert len(rows) == len(want["f"]) > 0
    for name in ("frames", "ids", "boxes", "conf"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
    assert TrackRows().table().boxes.shape == (0, 4)


def test_track_rows_hold_56_bytes_a_row():
    """8 (frame) + 8 (identity) + 32 (box) + 8 (score); the arrays double when full, so
    at most twice that is held."""
    rows = TrackRows()
    for frame in range(1, 5001):
        rows.extend(np.full(20, frame), np.arange(20), np.ones((20, 4)), np.ones(20))
    assert len(rows) == 100_000
    assert 56 * len(rows) <= rows.nbytes <= 2 * 56 * len(rows)
