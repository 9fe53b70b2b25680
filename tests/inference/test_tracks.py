"""The track layer: confirmation, coasting, identities, and re-identification of lost
tracks after an occlusion."""

import numpy as np

from pgm.inference.tracks import TrackManager

F = np.array([[1.0, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]])
H = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0]])


def walker(t, x0=0.0, vx=2.0):
    return np.array([x0 + vx * t, vx, 50.0, 0.0])


def run(manager, frames):
    """Feed states per frame; returns the reported ids per frame."""
    out = []
    for states in frames:
        out.append([t.track_id for t in manager.update(np.array(states).reshape(-1, 4))])
    return out


def test_confirmation_and_coasting_without_a_lost_stage():
    m = TrackManager(F, H, np.array([3.0, 3.0]), confirm_hits=3, max_coast=2)
    frames = [[walker(t)] for t in range(5)] + [[]] * 3 + [[walker(t)] for t in range(8, 12)]
    ids = run(m, frames)
    assert ids[:2] == [[], []] and ids[2] == [1]  # confirmed at the third hit
    assert ids[5] == [1] and ids[6] == [1] and ids[7] == []  # coasts 2 frames, then dropped
    assert ids[-1] == [2]  # the same walker comes back as a new identity


def test_lost_track_is_re_identified_and_reported_after_fresh_hits():
    m = TrackManager(F, H, np.array([3.0, 3.0]), confirm_hits=3, max_coast=2, max_lost=6)
    frames = [[walker(t)] for t in range(5)] + [[]] * 5 + [[walker(t)] for t in range(10, 16)]
    ids = run(m, frames)
    assert ids[6] == [1] and ids[7] == [] and ids[9] == []  # coasting, then lost (hidden)
    assert ids[10] == [] and ids[11] == []  # re-attached but not yet reported
    assert ids[12] == [1] and ids[-1] == [1]  # the old identity, no new one burnt
    assert max(t.track_id for t in m.tracks) == 1


def test_a_track_lost_longer_than_max_lost_is_forgotten():
    m = TrackManager(F, H, np.array([3.0, 3.0]), confirm_hits=3, max_coast=2, max_lost=4)
    frames = [[walker(t)] for t in range(5)] + [[]] * 6 + [[walker(t)] for t in range(11, 16)]
    ids = run(m, frames)
    assert ids[-1] == [2]


def test_lost_tracks_do_not_steal_estimates_from_active_ones():
    m = TrackManager(F, H, np.array([3.0, 3.0]), confirm_hits=2, max_coast=1, max_lost=10)
    a = [walker(t) for t in range(12)]
    b = [walker(t, x0=1.0) for t in range(12)]  # a second walker right beside the first
    frames = [[a[t], b[t]] for t in range(4)] + [[a[t]] for t in range(4, 12)]
    ids = run(m, frames)
    # the first walker keeps its identity; the hidden one is never reported meanwhile
    assert all(len(i) == 1 for i in ids[6:])
    assert len({i[0] for i in ids[6:]}) == 1


def test_one_matching_two_rounds_recent_first_then_lost():
    from pgm.inference.tracks import match

    # track 0 recent, track 1 lost; both prefer measurement 0: the recent one takes it,
    # the lost one gets what is left if it is valid
    cost = np.array([[0.2, 0.9], [0.1, 0.4]])
    t, m = match(cost, cost < 0.5, lost=[False, True])
    assert t.tolist() == [0, 1] and m.tolist() == [0, 1]
    t, m = match(cost, cost < 0.3, lost=[False, True])  # the left-over pair is not valid
    assert t.tolist() == [0] and m.tolist() == [0]
    t, m = match(np.zeros((0, 2)), np.zeros((0, 2), bool), lost=[])
    assert t.size == 0 and m.size == 0


def test_one_life_cycle_for_plates_and_phd():
    from pgm.inference.tracks import Track, confirm_tracks, reported, update_tracks

    tracks = [Track(np.zeros(2)) for _ in range(3)]
    tracks[2].track_id, tracks[2].misses = 7, 3  # a lost confirmed track
    keep = update_tracks(tracks, np.array([0, 2]), confirm_hits=2, max_coast=1, max_lost=5,
                         hit_log_odds=1.0, miss_log_odds=1.0)
    assert keep.tolist() == [True, False, True]  # the tentative track 1 missed: ended
    assert tracks[2].recovering  # re-attached: reported again after 2 hits in a row
    nxt = confirm_tracks([t for t, k in zip(tracks, keep, strict=True) if k], 2, next_id=8)
    assert tracks[0].track_id == 8 and nxt == 9
    assert reported(tracks, max_coast=1).tolist() == [True, False, False]


def test_a_gap_two_tracks_share_at_both_ends_is_not_filled():
    """Gap filling's birth rule: a track reported at frame 4 and again at 7 fills frames 5
    and 6, unless another track's boxes overlap its own (IoU above ``birth_iou``) at both
    frames 4 and 7 — a second track on the same object, which reported it meanwhile; one
    that overlaps at one end only (a crossing) leaves the gap filled."""
    from pgm.core.plate import Lifecycle
    from pgm.inference.plates import _filled_gaps
    from pgm.inference.tracks import Track

    lc = Lifecycle(fill_gaps=3, fill_after=1, birth_iou=0.3)
    box_a = {4: [100.0, 100, 40, 100], 7: [130.0, 100, 40, 100]}  # (cx, cy, w, h)
    twin = {t: [100.0 + 10 * (t - 4) + 4, 100, 40, 100] for t in (4, 5, 6, 7)}
    crossing = {t: [100.0 + 30 * (t - 4) + 4, 100, 40, 100] for t in (4, 5, 6, 7)}

    def fill(other):
        a = Track(state=np.zeros(4), track_id=1, streak=3)
        b = Track(state=np.zeros(4), track_id=2, streak=3)
        out = None
        for t in (4, 5, 6, 7):
            boxes = np.array([box_a.get(t, [0.0] * 4), other.get(t, [0.0] * 4)])
            out = _filled_gaps([a, b], t, boxes, np.array([t in box_a, t in other]),
                               np.ones(2), lc)
            assert t == 7 or out is None
        return out

    assert fill(twin) is None
    frames, ids, filled, _ = fill(crossing)
    assert frames.tolist() == [5, 6] and ids.tolist() == [1, 1]
    np.testing.assert_allclose(filled, [[110.0, 100, 40, 100], [120.0, 100, 40, 100]])
    assert fill({})[0].tolist() == [5, 6]
