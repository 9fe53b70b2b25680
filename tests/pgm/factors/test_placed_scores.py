"""The ``"placed"`` score map: the share cut relaxed where the tracks show the detections
below it placed as well as the best-scored ones
(:class:`pgm.factors.persistent_quantiles.PersistentQuantiles` with ``placed=True``).

The oracle scene: people walking, each detected by a box on them (IoU with the true box
above 0.8) scored high, and, for some, a second box off by 0.6 of its width (IoU 0.25:
near the person, not on them) scored below every box on a person — what the shared
detectors put in their lowest scores. The tracker's predicted boxes are stood in for by
the true boxes, so the labels are known exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.pgm.factors.test_scores import MAPS


def placed_scene(rng, frames=200, people=10, misplaced=0.0):
    """Per frame: (centre boxes, scores, the people's true boxes, is_misplaced).
    ``misplaced`` of the boxes (on average) are a second box beside a person."""
    pos = rng.uniform(100, 900, (people, 2))
    vel = rng.normal(0, 2, (people, 2))
    size = np.array([40.0, 100.0])
    out = []
    for _ in range(frames):
        pos = pos + vel
        truth = np.column_stack([pos, np.tile(size, (people, 1))])
        on = truth + np.column_stack([rng.normal(0, 1.0, (people, 2)), np.zeros((people, 2))])
        k = rng.binomial(people, misplaced / (1 - misplaced)) if misplaced else 0
        who = rng.choice(people, k, replace=False)
        side = rng.choice([-1.0, 1.0], k)
        off = truth[who] + np.column_stack([0.6 * size[0] * side, np.zeros((k, 3))])
        boxes = np.concatenate([on, off])
        scores = np.r_[rng.normal(5.0, 1.0, people), rng.normal(-5.0, 1.0, k)]
        out.append((boxes, scores, truth, np.r_[np.zeros(people, bool), np.ones(k, bool)]))
    return out


def test_placed_is_the_gated_quantile_where_the_lowest_scores_are_misplaced():
    """Oracle: with 30 % of the boxes beside a person and scored lowest, the placement
    curve falls where they are (its bins below their share at most a tenth of its top,
    those above within a tenth of it), the detections below the threshold are not placed
    as a group, ``u_p`` stays above the threshold's 0.2, so nothing is lifted and every
    frame's map is the gated quantile's, exactly."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    scene = placed_scene(np.random.default_rng(31), misplaced=0.3)
    placed, gated = PersistentQuantiles(placed=True, share=0.2), PersistentQuantiles()
    for boxes, scores, truth, _ in scene:
        q = placed.update(boxes, scores, truth)
        np.testing.assert_array_equal(q, gated.update(boxes, scores))
    curve = placed.placement.curve / placed.placement.curve[-1]
    assert np.all(curve[:5] < 0.1) and np.all(curve[7:] > 0.9)
    assert placed.placed_quantile() > 0.2


def test_placed_lifts_what_a_higher_threshold_left_every_box_on_a_person():
    """The same people with no box beside them (the detector run at a higher threshold):
    every bin is placed as well as the top, ``u_p`` falls to 0 and the lowest fifth,
    which the gated quantile cuts, is lifted to the threshold (``q = max(u, 0.2)``);
    the same values, exactly, for any strictly increasing map of the scores."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    scene = placed_scene(np.random.default_rng(32))
    ref = None
    for name, f in [("none", lambda s: s)] + list(MAPS.items()):
        all_scores = f(np.concatenate([s for _, s, _, _ in scene]) * 20 + 40)
        split = np.cumsum([len(s) for _, s, _, _ in scene])[:-1]
        placed, gated = PersistentQuantiles(placed=True, share=0.2), PersistentQuantiles()
        got = []
        for (boxes, _, truth, _), s in zip(scene, np.split(all_scores, split), strict=True):
            q, g = placed.update(boxes, s, truth), gated.update(boxes, s)
            lifted = placed.placed_quantile() <= g
            np.testing.assert_array_equal(q, np.where(lifted, np.maximum(g, 0.2), g))
            got.append(q)
        assert placed.placed_quantile() == 0.0
        last = np.concatenate(got[-50:])
        assert np.all(last >= 0.2)  # every box kept; the gated quantile cuts a fifth
        if ref is None:
            ref = np.concatenate(got)
        np.testing.assert_array_equal(np.concatenate(got), ref, err_msg=name)


def test_placed_lifts_nothing_before_a_box_is_labelled():
    """Without references (no tracked person yet) ``u_p`` is 1 and the map is the gated
    quantile; a box far from every reference is not labelled."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    scene = placed_scene(np.random.default_rng(33), frames=30)
    placed, gated = PersistentQuantiles(placed=True), PersistentQuantiles()
    far = np.array([[5000.0, 5000.0, 40.0, 100.0]])
    for boxes, scores, _, _ in scene:
        np.testing.assert_array_equal(placed.update(boxes, scores, far),
                                      gated.update(boxes, scores))
        np.testing.assert_array_equal(placed.update(boxes, scores, None),
                                      gated.update(boxes, scores))
    assert placed.placement.labelled == 0 and placed.placed_quantile() == 1.0


def test_placed_settings_are_checked_and_kept_with_the_factor():
    from pgm.core.factor import factor_from_dict
    from pgm.factors.detection_association import DetectionAssociation
    from pgm.factors.persistent_quantiles import PLACED_LEVEL, PersistentQuantiles

    both = PersistentQuantiles(rebase=True, placed=True)  # "placed-rebased"
    assert both.rebase and both.placement is not None
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="placed_level"):
            DetectionAssociation("box", score_map="placed", placed_level=bad)
    f = DetectionAssociation("box", score_map="placed", placed_level=0.6,
                             rounds=[{"iou": 0.3, "min_score": 0.25}])
    g = factor_from_dict(f.to_dict())
    assert g.placed_level == 0.6 and g.score_map == "placed"
    m = g.score_model()
    assert (m.level, m.share) == (0.6, 0.25)
    # a core without a score threshold cuts nothing, and so lifts nothing
    assert DetectionAssociation("box", score_map="placed").score_model().share == 0.0
    assert "placed_level" not in DetectionAssociation("box").to_dict()["params"]
    assert DetectionAssociation("box").placed_level == PLACED_LEVEL
    r = DetectionAssociation("box", score_map="placed-rebased", placed_level=0.7,
                             rounds=[{"iou": 0.3, "min_score": 0.2}])
    m = factor_from_dict(r.to_dict()).score_model()
    assert m.rebase and m.placement is not None and (m.level, m.share) == (0.7, 0.2)
    # the gate's confidence: checked, kept, passed to every gated map's model
    for bad in (0.3, 1.0, float("nan")):
        with pytest.raises(ValueError, match="gate_confidence"):
            DetectionAssociation("box", score_map="placed-over", gate_confidence=bad)
    assert "gate_confidence" not in DetectionAssociation("box").to_dict()["params"]
    for score_map in ("quantile-gated", "quantile-rebased", "placed-rebased", "placed-over"):
        c = factor_from_dict(DetectionAssociation("box", score_map=score_map,
                                                  gate_confidence=0.9).to_dict())
        assert c.gate_confidence == 0.9 and c.score_model().confidence == 0.9


def test_placed_goes_down_from_the_threshold_one_bin_at_a_time():
    """``u_p`` from labels set by hand on 1 000 scores (20 bins of 50): going down from
    the threshold's bin, each group from the bin reached up to it must be on its objects
    at least ``level`` times as often as the top (each rate shrunk by five
    pseudo-detections placed badly); the first group that is not stops it, even where a
    larger group below would pass, and a bin with a few labels lifts nothing."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    def u_p(on_bins, off_bins, few=False):
        pq = PersistentQuantiles(placed=True, share=0.2, level=0.8)
        scores = np.arange(1000.0)
        pq.model.seen.add(scores)
        label = np.isin(scores // 50, on_bins + off_bins)
        if few:  # two labels in bin 3, the bins above as before
            label &= (scores // 50 != 3) | (scores % 50 < 2)
        pq.placement.add_labels(scores[label], np.isin(scores // 50, on_bins)[label])
        return pq.placed_quantile()

    above = list(range(4, 20))  # the bins above the threshold's, all placed
    assert u_p(above + [0, 1, 2, 3], []) == 0.0
    assert u_p(above + [0, 1, 3], [2]) == 0.15  # stops at bin 2's group
    assert u_p(above + [0, 1, 2], [3]) == 1.0  # the bin just below is not placed
    assert u_p(above + [0, 1, 2, 3], [], few=True) == 1.0


def with_clutter(scene, rng, per_frame=10):
    """``scene`` with ``per_frame`` false boxes a frame scored below every box of it (a
    detector run at a lower threshold) and placed far from everyone, each frame anew (never
    found again); the clutter flagged as misplaced too, and as ``clutter``."""
    out = []
    low = min(float(s.min()) for _, s, _, _ in scene)
    for boxes, scores, truth, off in scene:
        fake = np.column_stack([rng.uniform(2000, 9000, (per_frame, 2)),
                                np.tile([40.0, 100.0], (per_frame, 1))])
        out.append((np.concatenate([boxes, fake]),
                    np.r_[scores, low - 10.0 - rng.random(per_frame)], truth,
                    np.r_[off, np.ones(per_frame, bool)],
                    np.r_[np.zeros(len(scores), bool), np.ones(per_frame, bool)]))
    return out


def test_placed_rebased_cuts_the_usual_share_under_a_lower_threshold():
    """Oracle: people with 30 % of the boxes beside a person and scored lowest, as the
    shared detectors' output. Run as it is, ``"placed"`` cuts the lowest fifth (boxes
    beside a person: the placement curve shows them misplaced). Run at a lower threshold
    (as many clutter boxes again, scored below all, never found again) the gate reads the
    clutter as 0, and ``"placed"`` then reads the boxes beside a person as above the fifth
    the clutter took, keeping most of them; ``"placed-rebased"`` cuts the fifth from the
    detections above the clutter, so it keeps the boxes on a person and cuts those beside
    one as ``"placed"`` did without the clutter (within 0.05 of its share), and every
    clutter box (over the last 100 frames: the first learn where the clutter is)."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    scene = placed_scene(np.random.default_rng(34), misplaced=0.3)
    low = with_clutter(scene, np.random.default_rng(35), per_frame=14)
    clean = PersistentQuantiles(placed=True, share=0.2)
    placed = PersistentQuantiles(placed=True, share=0.2)
    rebased = PersistentQuantiles(placed=True, rebase=True, share=0.2)
    kept = {"clean": [], "placed": [], "rebased": []}
    for t, ((b0, s0, truth, off0), (b, s, _, off, clutter)) in enumerate(zip(scene, low,
                                                                             strict=True)):
        q0, q1, q2 = (clean.update(b0, s0, truth), placed.update(b, s, truth),
                      rebased.update(b, s, truth))
        if t >= len(scene) - 100:
            assert np.all(q2[clutter] == 0.0)
            kept["clean"].append(q0[off0] >= 0.2)
            kept["placed"].append(q1[off & ~clutter] >= 0.2)
            kept["rebased"].append(q2[off & ~clutter] >= 0.2)
            assert np.all(q2[~off] >= 0.2)  # every box on a person kept
    share = {k: float(np.mean(np.concatenate(v))) for k, v in kept.items()}
    assert rebased.threshold_quantile() > 0.3  # the clutter seen (about 0.4 of the boxes)
    assert share["placed"] > share["clean"] + 0.3  # the clutter took the fifth
    assert abs(share["rebased"] - share["clean"]) < 0.05, share


def test_placed_rebased_is_placed_where_the_video_shows_no_clutter():
    """Wherever ``u* = 0`` (no clutter the video can see) the two maps are equal, exactly;
    on a scene of people alone that is every frame."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    for misplaced in (0.0, 0.3):
        scene = placed_scene(np.random.default_rng(36), frames=120, misplaced=misplaced)
        placed = PersistentQuantiles(placed=True, share=0.2)
        rebased = PersistentQuantiles(placed=True, rebase=True, share=0.2)
        for boxes, scores, truth, _ in scene:
            q, r = placed.update(boxes, scores, truth), rebased.update(boxes, scores, truth)
            assert rebased.threshold_quantile() == 0.0
            np.testing.assert_array_equal(r, q)


def test_placed_over_lifts_the_boxes_on_a_track_that_the_clutter_gate_cuts():
    """``"placed-over"``: with the clutter gate held at ``u* = 0.3`` (a stand-in for the
    crowd's bias: people alone, every box on a person, none clutter) and the placement
    showing every score placed (``u_p = 0``), a box below ``u*`` on a reference box is
    kept at the threshold (``q = 0.2``) where ``"placed-rebased"`` reads it as 0; a box
    below ``u*`` on no reference box (clutter far from everyone) stays 0; above ``u*``
    the two maps are equal, exactly."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    class Held(PersistentQuantiles):
        def threshold_quantile(self) -> float:
            return 0.3

    scene = with_clutter(placed_scene(np.random.default_rng(37), frames=150),
                         np.random.default_rng(38), per_frame=2)
    over = Held(placed=True, rebase=True, share=0.2, over_clutter=True)
    rebased = Held(placed=True, rebase=True, share=0.2)
    below_on, below_off = [], []
    for t, (boxes, scores, truth, _, clutter) in enumerate(scene):
        q, r = over.update(boxes, scores, truth), rebased.update(boxes, scores, truth)
        u = over.model.seen.mid_ranks(scores)
        np.testing.assert_array_equal(q[u >= 0.3], r[u >= 0.3])
        assert np.all(r[u < 0.3] == 0.0) and np.all(q[clutter] == 0.0)
        if t >= 50:
            below_on.append(q[(u < 0.3) & ~clutter])
            below_off.append(q[(u < 0.3) & clutter])
    assert over.placed_quantile(0.3 + 0.2 * 0.7) == 0.0
    on, off = np.concatenate(below_on), np.concatenate(below_off)
    assert on.size > 100 and np.all(on == 0.2)
    assert off.size > 100 and np.all(off == 0.0)


def test_placed_over_is_checked_and_made_by_the_factor():
    from pgm.factors.detection_association import DetectionAssociation
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    with pytest.raises(ValueError, match="over_clutter needs placed"):
        PersistentQuantiles(over_clutter=True)
    m = DetectionAssociation("box", score_map="placed-over",
                             rounds=[{"iou": 0.3, "min_score": 0.2}]).score_model()
    assert m.over_clutter and m.rebase and m.placement is not None and m.share == 0.2
    m = DetectionAssociation("box", score_map="placed-rebased",
                             rounds=[{"iou": 0.3, "min_score": 0.2}]).score_model()
    assert not m.over_clutter and m.rebase
