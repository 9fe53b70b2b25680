"""Detection scores in the PHD measurement model: settings, the two-class score mixture
and its online calibration (never from ground truth)."""

import dataclasses

import numpy as np
import pytest

from pgm import FactorGraph, Variable
from pgm.factors.multitarget import IntensityPrior, PHDLikelihood
from pgm.factors.scores import ScoreCalibration, ScoreMixture, ScoreSettings, shadowed


def two_class_scores(rng, n=4000, pi=0.7, clutter=(10.0, 4.0), target=(60.0, 15.0)):
    """Scores of a known mixture: a share ``pi`` from the target class."""
    is_target = rng.random(n) < pi
    s = np.where(is_target, rng.normal(*target, n), rng.normal(*clutter, n))
    return s, is_target


def test_the_mixture_recovers_a_known_two_class_score_distribution():
    s, is_target = two_class_scores(np.random.default_rng(0))
    m = ScoreMixture.initial(s).fit(s, 200)
    assert abs(m.weight - 0.7) < 0.03
    np.testing.assert_allclose(m.mean, [10.0, 60.0], atol=1.5)
    np.testing.assert_allclose(np.sqrt(m.var), [4.0, 15.0], rtol=0.1)
    # the posterior separates the classes it was never told about
    acc = np.mean((m.responsibility(s) >= 0.5) == is_target)
    assert acc > 0.95


def test_the_fit_does_not_depend_on_the_detectors_units():
    """MOT15 and MOT16 scores differ by scale and offset: EM is affine-equivariant."""
    s, _ = two_class_scores(np.random.default_rng(1))
    a = ScoreMixture.initial(s).fit(s, 200)
    t = 0.05 * s - 1.0  # another detector's units
    b = ScoreMixture.initial(t).fit(t, 200)
    assert b.weight == pytest.approx(a.weight, abs=1e-6)
    np.testing.assert_allclose(b.mean, 0.05 * a.mean - 1.0, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(a.responsibility(s), b.responsibility(t), atol=1e-6)
    np.testing.assert_allclose(a.log_ratio(s), b.log_ratio(t), atol=1e-5)


def test_the_likelihood_ratio_is_monotone_and_saturates():
    s, _ = two_class_scores(np.random.default_rng(2))
    m = ScoreMixture.initial(s).fit(s, 200)
    grid = np.linspace(-50, 200, 500)
    lr = m.log_ratio(grid)
    assert np.all(np.diff(lr) >= -1e-12)
    assert lr[0] == lr[1] and lr[-1] == lr[-2]  # clipped outside the two means


def test_online_calibration_is_score_blind_until_it_has_enough_scores():
    cal = ScoreCalibration(ScoreSettings(model="mixture", min_samples=100, max_ratio=50.0,
                                         birth_min_prob=0.5))
    rng = np.random.default_rng(3)
    cal.observe(rng.normal(60, 15, 20))
    assert not cal.ready
    np.testing.assert_array_equal(cal.clutter_scale([0.0, 100.0]), [1.0, 1.0])
    assert cal.birth_mask([0.0, 100.0]).all()
    for _ in range(30):
        s, _ = two_class_scores(rng, n=8)
        cal.observe(s)
    assert cal.ready
    k = cal.clutter_scale([10.0, 60.0])
    assert k[0] > 1.0 > k[1]  # low score: more clutter-like; high score: less
    assert k[1] == pytest.approx(1 / 50.0)  # clipped at max_ratio
    np.testing.assert_array_equal(cal.birth_mask([10.0, 60.0]), [False, True])


@pytest.mark.parametrize("temper", [1.0, 0.5])
def test_persisting_targets_scored_by_the_marginal_density(temper):
    """``persisting="all"``: the corrector is divided by the marginal score density
    ``f = π f_T + (1 − π) f_C``, so κ carries ``(f_C/f)^γ`` and births ``(f_T/f)^γ``,
    computed here from the fitted mixture's Gaussian densities by hand."""
    rng = np.random.default_rng(5)
    settings = ScoreSettings(model="mixture", temper=temper, birth_min_prob=0.0,
                             persisting="all", max_ratio=1e300)
    cal = ScoreCalibration(settings)
    for _ in range(100):
        cal.observe(two_class_scores(rng, n=10)[0])
    m = cal.mixture
    s = np.array([m.mean[0], 30.0, m.mean[1]])  # inside the span: no clipping

    def normal(x, mu, var):
        return np.exp(-0.5 * (x - mu) ** 2 / var) / np.sqrt(2 * np.pi * var)

    f_c, f_t = normal(s, m.mean[0], m.var[0]), normal(s, m.mean[1], m.var[1])
    f = m.weight * f_t + (1 - m.weight) * f_c
    on_kappa, on_nu = cal.terms(s)
    np.testing.assert_allclose(on_kappa, (f_c / f) ** temper, rtol=1e-9)
    np.testing.assert_allclose(on_nu, (f_t / f) ** temper, rtol=1e-9)
    # a low score makes a detection at most 1/(1 - π) times more clutter-like, where the
    # literal model ("target") makes it f_C/f_T times: a tracked target's low-score
    # detection is not written off
    assert on_kappa[0] <= (1 / (1 - m.weight)) ** temper + 1e-12
    literal = ScoreCalibration(dataclasses.replace(settings, persisting="target"))
    literal.mixture = m
    assert literal.terms(s)[0][0] > 10 * on_kappa[0]
    np.testing.assert_array_equal(literal.terms(s)[1], [1.0, 1.0, 1.0])  # no gate


def test_shadowed_detections_by_hand():
    boxes = np.array([[0.0, 0, 10, 20],     # A, score 0.9
                      [0, 5, 10, 20],       # B: IoU with A 15/25 = 0.6, score 0.5
                      [100, 0, 10, 20],     # C: alone, score 0.1
                      [0, 10, 10, 20],      # D: IoU with A 10/30 = 1/3, with B 15/25
                      [100, 0, 10, 20]])    # E: C's twin, same score: ties shadow neither
    scores = np.array([0.9, 0.5, 0.1, 0.7, 0.1])
    # B is under A (0.6 >= 0.5); D is over B (0.7 > 0.5) and under A only at 1/3
    np.testing.assert_array_equal(shadowed(boxes, scores, 0.5),
                                  [False, True, False, False, False])
    np.testing.assert_array_equal(shadowed(boxes, scores, 0.3),
                                  [False, True, False, True, False])
    assert not shadowed(boxes[:1], scores[:1], 0.3).any()
    assert not shadowed(boxes, scores, 0.0).any()


def test_clutter_rate_from_the_mixture():
    cal = ScoreCalibration(ScoreSettings(model="mixture", clutter_from_scores=True))
    rng = np.random.default_rng(4)
    for _ in range(200):  # 10 detections a frame, 30 % clutter -> lambda_c about 3
        s, _ = two_class_scores(rng, n=10)
        cal.observe(s)
    assert cal.clutter_rate(99.0) == pytest.approx(3.0, abs=0.3)
    off = ScoreCalibration(ScoreSettings(model="mixture"))
    assert off.clutter_rate(2.0) == 2.0


@pytest.mark.parametrize("kw, name", [
    ({"temper": float("nan")}, "scores.temper"),
    ({"temper": -1.0}, "scores.temper"),
    ({"max_ratio": 0.5}, "scores.max_ratio"),
    ({"max_ratio": float("inf")}, "scores.max_ratio"),
    ({"birth_min_prob": 1.5}, "scores.birth_min_prob"),
    ({"birth_min_prob": float("nan")}, "scores.birth_min_prob"),
    ({"min_samples": 1}, "scores.min_samples"),
    ({"em_iter": 0}, "scores.em_iter"),
    ({"model": "logistic"}, "scores.model"),
    ({"clutter_from_scores": "yes"}, "scores.clutter_from_scores"),
    ({"persisting": "some"}, "scores.persisting"),
    ({"shadow_iou": 1.5}, "scores.shadow_iou"),
    ({"shadow_iou": float("nan")}, "scores.shadow_iou"),
])
def test_bad_settings_name_the_parameter(kw, name):
    with pytest.raises(ValueError, match=name):
        ScoreSettings(**kw)


def test_score_settings_are_saved_with_the_factor_and_loaded_without_code(tmp_path):
    def graph(scores):
        f = PHDLikelihood("targets", H=[[1.0, 0, 0, 0], [0, 0, 1.0, 0]], R=[4.0, 4.0],
                          scores=scores)
        return FactorGraph([Variable("targets", 4, role="set")],
                           [IntensityPrior("targets", mean=np.zeros(4)), f])

    g = graph({"model": "mixture", "temper": 0.5, "birth_min_prob": 0.2})
    phd_of = lambda graph: next(f for f in graph.factors.values()  # noqa: E731
                                if isinstance(f, PHDLikelihood))
    p = phd_of(g).params()
    assert p["scores"]["temper"] == 0.5 and p["scores"]["model"] == "mixture"
    g.save(tmp_path / "m.json")
    back = FactorGraph.load(tmp_path / "m.json")
    assert back == g
    assert phd_of(back).scores == ScoreSettings(
        model="mixture", temper=0.5, birth_min_prob=0.2)
    # score-blind factors save exactly as before scores were used
    assert "scores" not in phd_of(graph(None)).params()
    with pytest.raises(ValueError, match="unknown setting"):
        graph({"model": "mixture", "gamma": 1.0})


# -- the learned score map of the tracking-by-detection cores --------------------------

MAPS = {
    "affine": lambda s: 3.0 * s - 7.0,
    "power": lambda s: np.sqrt(s - s.min() + 1.0),
    "probability": lambda s: 1.0 / (1.0 + np.exp(-(s - 40.0) / 20.0)),
    "logit": lambda s: (s - 40.0) / 20.0,
    "rank": lambda s: np.searchsorted(np.sort(s), s, side="right") / s.size,
}


def persistent_scene(rng, frames=150, people=6, pi_false=0.35, target=(2.0, 1.0),
                     clutter=(0.0, 1.0)):
    """Per frame: ``people`` walkers detected with probability 0.9 (their boxes move a
    little each frame) and a Poisson number of false detections placed anywhere (never
    found again), scores from two known Gaussians. Returns the frames' (centre boxes,
    scores, is_true)."""
    pos = rng.uniform(100, 900, (people, 2))
    vel = rng.normal(0, 2, (people, 2))
    out = []
    n_false = people * pi_false / (1 - pi_false)
    for _ in range(frames):
        pos = pos + vel
        seen = rng.random(people) < 0.9
        tb = np.column_stack([pos[seen], np.full((seen.sum(), 2), [40.0, 100.0])])
        k = rng.poisson(n_false)
        fb = np.column_stack([rng.uniform(0, 1000, (k, 2)), np.full((k, 2), [40.0, 100.0])])
        boxes = np.concatenate([tb, fb])
        truth = np.r_[np.ones(len(tb), bool), np.zeros(k, bool)]
        scores = np.where(truth, rng.normal(*target, len(truth)), rng.normal(*clutter, len(truth)))
        out.append((boxes, scores, truth))
    return out


def test_score_ranks_are_the_same_for_any_increasing_map():
    from pgm.factors.scores import mid_ranks

    s = np.array([3.0, 1.0, 2.0, 2.0, 10.0])
    u = mid_ranks(np.sort(s), s)
    np.testing.assert_allclose(u, [0.7, 0.1, 0.4, 0.4, 0.9])
    for f in MAPS.values():
        np.testing.assert_array_equal(mid_ranks(np.sort(f(s)), f(s)), u)
    np.testing.assert_array_equal(mid_ranks(np.zeros(0), s), np.full(5, 0.5))


def test_the_learned_probability_is_invariant_to_the_detectors_scale():
    """Fed the same detections with scores through any strictly increasing map, the model
    gives the same probabilities, exactly."""
    from pgm.factors.scores import PersistenceScoreModel

    scene = persistent_scene(np.random.default_rng(3), frames=60)
    all_scores = np.concatenate([s for _, s, _ in scene]) * 20 + 40  # positive, MOT15-like
    split = np.cumsum([len(s) for _, s, _ in scene])[:-1]
    ref = None
    for name, f in [("none", lambda s: s)] + list(MAPS.items()):
        mapped = np.split(f(all_scores), split)
        m = PersistenceScoreModel()
        p = np.concatenate([m.update(b, s) for (b, _, _), s in zip(scene, mapped, strict=True)])
        if ref is None:
            ref = p
        np.testing.assert_array_equal(p, ref, err_msg=name)


def test_the_learned_probability_recovers_the_true_share_of_targets():
    """Oracle: with ``ρ_T`` and ``ρ_F`` the rates at which the scene's target and false
    detections are found again (measured from the model's own labels and the scene's
    truth), the model's probability is ``(ρ_F + (ρ_T − ρ_F) P(target | s)) / ρ_T``, with
    the posterior in closed form from the scene's two known score densities — near the
    posterior itself when false detections are seldom found again. Checked in score
    quintiles, within four binomial standard errors of each quintile's count."""
    from scipy.stats import norm

    from pgm.factors.scores import PersistenceScoreModel

    rng = np.random.default_rng(7)
    scene = persistent_scene(rng, frames=300, people=8)
    m = PersistenceScoreModel(buffer=0.25, gate=0.3)
    found = []
    for boxes, scores, _ in scene:
        m.update(boxes, scores)
        found.append(m.last_labelled[1])
    found = np.concatenate(found)
    s = np.concatenate([x for _, x, _ in scene])
    truth = np.concatenate([t for _, _, t in scene])
    pi = truth.mean()
    post = pi * norm.pdf(s, 2, 1) / (pi * norm.pdf(s, 2, 1) + (1 - pi) * norm.pdf(s, 0, 1))
    labelled = np.concatenate([t for _, _, t in scene[:-1]])
    rho_t, rho_f = found[labelled].mean(), found[~labelled].mean()
    assert 0.85 < rho_t < 0.95 and rho_f < 0.15  # the detector's 0.9; chance overlaps
    post = (rho_f + (rho_t - rho_f) * post) / rho_t
    p = m.probability(s)
    assert np.all(np.diff(m.curve) >= -1e-12)  # a higher score never says less
    edges = np.quantile(s, np.linspace(0, 1, 6))
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (s >= lo) & (s <= hi)
        se = np.sqrt(post[inside].mean() * (1 - post[inside].mean()) / inside.sum())
        # + 0.03: the curve is read in 20 quantile bins and its top bin stands for ρ_T
        # (measured here: 0.015 to 0.028 above the posterior in the lower quintiles)
        assert abs(p[inside].mean() - post[inside].mean()) < 4 * se + 0.03, (lo, hi)
    # and it separates the classes it was never told about
    assert np.mean((p >= 0.5) == truth) > 0.8


def test_before_anything_is_labelled_every_detection_is_taken_as_it_comes():
    from pgm.factors.scores import PersistenceScoreModel

    m = PersistenceScoreModel()
    b = np.array([[10.0, 10.0, 4.0, 8.0], [50.0, 50.0, 4.0, 8.0]])
    np.testing.assert_array_equal(m.update(b, np.array([0.1, 0.9])), [1.0, 1.0])
    with pytest.raises(ValueError, match="scores"):
        m.update(b, np.array([0.5]))
    with pytest.raises(ValueError, match="bins"):
        PersistenceScoreModel(bins=0)
    with pytest.raises(ValueError, match="buffer"):
        PersistenceScoreModel(buffer=float("nan"))


def test_the_phd_learned_score_terms_are_invariant_and_favour_confident_detections():
    """The PHD's ``"learned"`` score model: per-detection clutter and birth terms that
    are the same for any strictly increasing map of the scores, with more clutter
    written against a low-score detection than a high-score one."""
    scene = persistent_scene(np.random.default_rng(5), frames=80)
    all_scores = np.concatenate([s for _, s, _ in scene])
    split = np.cumsum([len(s) for _, s, _ in scene])[:-1]
    settings = ScoreSettings(model="learned", birth_min_prob=0.5, min_samples=50)
    ref = None
    for name, f in [("none", lambda s: s)] + list(MAPS.items()):
        cal = ScoreCalibration(settings)
        terms = []
        for (b, _, _), s in zip(scene, np.split(f(all_scores * 20 + 40), split), strict=True):
            xywh = np.concatenate([b[:, :2] - b[:, 2:] / 2, b[:, 2:]], axis=1)
            cal.observe(s, xywh)
            on_kappa, on_nu = cal.terms(s)
            terms.append(np.stack([on_kappa, on_nu]))
        terms = np.concatenate(terms, axis=1)
        if ref is None:
            ref = terms
        np.testing.assert_array_equal(terms, ref, err_msg=name)
    assert cal.ready
    truth = np.concatenate([t for _, _, t in scene])
    on_kappa = ref[0]
    # clutter is written more readily against false detections than against targets
    assert np.median(on_kappa[~truth]) > 2 * np.median(on_kappa[truth])
    with pytest.raises(ValueError, match="boxes"):
        ScoreCalibration(settings).observe(np.ones(2))


def test_score_quantiles_are_mid_ranks_among_every_score_so_far():
    """Oracle: each frame's quantiles are the mid-ranks among every finite score shown so
    far, this frame's included, also after the recent scores are merged into the rest
    (a small ``RECENT`` forces merges); non-finite scores get 0."""
    from pgm.factors.scores import ScoreQuantiles, mid_ranks

    rng = np.random.default_rng(5)
    q = ScoreQuantiles()
    q.seen.RECENT = 16
    seen = []
    for frame in range(60):
        s = np.round(rng.normal(size=rng.integers(0, 9)), 1)  # ties on purpose
        if frame % 7 == 3 and s.size:
            s[0] = np.nan
        got = q.update(np.ones((s.size, 4)), s)
        seen.extend(s[np.isfinite(s)])
        want = np.where(np.isfinite(s), mid_ranks(np.sort(seen), np.nan_to_num(s)), 0.0)
        np.testing.assert_allclose(got, want, atol=1e-15)
    np.testing.assert_array_equal(q.history, np.sort(seen))
    older, recent = q.seen._older.size, q.seen._recent.size
    assert older > 0 and recent <= max(16, 4 * np.sqrt(older))
    assert ScoreQuantiles().update(np.ones((1, 4)), np.array([np.nan])).tolist() == [0.0]


def test_sorted_scores_answer_as_the_one_sorted_array():
    """Oracle: the two-part store's sorted sequence, scores at every rank, counts and
    mid-ranks are those of one sorted array of every finite score added — with ties,
    NaN and infinite scores, empty frames, and merges (a small ``RECENT`` forces them)."""
    from pgm.factors.scores import mid_ranks
    from pgm.factors.sorted_scores import SortedScores

    rng = np.random.default_rng(3)
    store, every = SortedScores(), []
    store.RECENT = 23
    merges = 0
    for frame in range(120):
        s = np.round(rng.normal(size=rng.integers(0, 12)), 1)  # ties on purpose
        if frame % 9 == 4 and s.size:
            s[0] = np.nan
        if frame % 13 == 6 and s.size:
            s[-1] = np.inf
        before = store._older.size
        store.add(s)
        merges += store._older.size > before
        every.extend(s[np.isfinite(s)])
        want = np.sort(every)
        np.testing.assert_array_equal(store.sorted(), want)
        assert store.size == want.size
        if want.size:
            np.testing.assert_array_equal(store.at(np.arange(want.size)), want)
        probe = np.concatenate([want, [-np.inf, np.inf, np.nan, 0.05, -7.0, 7.0]])
        for side in ("left", "right"):
            np.testing.assert_array_equal(store.count(probe, side),
                                          np.searchsorted(want, probe, side=side))
        np.testing.assert_array_equal(store.mid_ranks(probe), mid_ranks(want, probe))
    assert merges >= 3 and store._recent.size > 0  # both parts in use at the end


def test_insert_sorted_is_np_insert_for_a_sorted_batch():
    """Oracle: ``np.insert`` itself, for batches placed by ``np.searchsorted`` (ties with
    the array and within the batch, empty batches and arrays, a boolean array beside)."""
    from pgm.factors.sorted_scores import insert_sorted

    rng = np.random.default_rng(5)
    for _ in range(200):
        arr = np.sort(np.round(rng.normal(size=rng.integers(0, 15)), 1))
        new = np.sort(np.round(rng.normal(size=rng.integers(0, 6)), 1))
        flags = rng.random(arr.size) < 0.5
        new_flags = rng.random(new.size) < 0.5
        for side in ("left", "right"):
            at = np.searchsorted(arr, new, side=side)
            got, got_flags = insert_sorted(at, arr.size, (arr, new), (flags, new_flags))
            np.testing.assert_array_equal(got, np.insert(arr, at, new))
            np.testing.assert_array_equal(got_flags, np.insert(flags, at, new_flags))
            assert got.dtype == arr.dtype and got_flags.dtype == bool


def test_persistence_model_refits_as_binning_every_labelled_score():
    """Oracle: the curve refitted each frame from the bins' starts and the two sorted
    parts is the curve of binning every labelled score by its quantile among every score
    so far, bit for bit — with tied scores, NaN scores, empty frames and merges of the
    recent part (a small ``RECENT`` forces them)."""
    from pgm.factors.persistence import PersistenceScoreModel, _pool_adjacent
    from pgm.factors.scores import mid_ranks

    def naive(m, labelled, found):
        u = mid_ranks(np.sort(m.history), labelled)
        k = np.minimum((u * m.bins).astype(int), m.bins - 1)
        count = np.bincount(k, minlength=m.bins).astype(float)
        hits = np.bincount(k, weights=found.astype(float), minlength=m.bins)
        overall = (hits.sum() + 1.0) / (len(labelled) + 1.0)
        w = m.prior_weight
        return _pool_adjacent((hits + w * overall) / np.maximum(count + w, 1e-12), count + w)

    rng = np.random.default_rng(11)
    for bins in (20, 3):
        m = PersistenceScoreModel(bins=bins)
        m.RECENT = m.seen.RECENT = 37  # merges of the labelled scores and of every score
        quiet = PersistenceScoreModel(bins=bins)  # fed by observe: the same model
        quiet.RECENT = quiet.seen.RECENT = 37
        labelled, found, previous = [], [], np.zeros(0)
        people = rng.uniform(0, 400, (6, 4))
        people[:, 2:] = 30.0
        for frame in range(150):
            keep = rng.random(6) < 0.8
            boxes = people[keep] + rng.normal(0, 2, (keep.sum(), 4))
            clutter = rng.uniform(0, 400, (rng.poisson(2), 4))
            clutter[:, 2:] = 30.0
            b = np.concatenate([boxes, clutter]) if frame % 17 else np.zeros((0, 4))
            s = np.round(rng.normal(size=len(b)), 1)  # ties on purpose
            if len(s) and frame % 5 == 0:
                s[0] = np.nan
            p = m.update(b, s)
            quiet.observe(b, s)
            np.testing.assert_array_equal(p, m.probability(s))
            np.testing.assert_array_equal(quiet.curve, m.curve)
            scores, flags = m.last_labelled  # the previous frame's finite scores, in order
            np.testing.assert_array_equal(scores, previous[np.isfinite(previous)])
            labelled.append(scores)
            found.append(flags)
            previous = s
            if sum(x.size for x in labelled):
                np.testing.assert_array_equal(
                    m.curve, naive(m, np.concatenate(labelled), np.concatenate(found)))
        assert m._older.size > 0 and m.seen._older.size > 0  # merges happened


def test_persistent_quantiles_are_the_plain_quantiles_while_nothing_is_clutter():
    """Oracle: on detections that are all found again (every bin's probability at the
    top's), ``u*`` is 0 and each frame's map, gated or rebased, is the plain mid-rank
    quantile, :class:`ScoreQuantiles`', exactly."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles
    from pgm.factors.scores import ScoreQuantiles

    scene = persistent_scene(np.random.default_rng(11), frames=80, pi_false=0.0)
    gated, rebased, plain = PersistentQuantiles(), PersistentQuantiles(rebase=True), \
        ScoreQuantiles()
    for boxes, scores, _ in scene:
        want = plain.update(boxes, scores)
        np.testing.assert_allclose(gated.update(boxes, scores), want, atol=1e-15)
        np.testing.assert_allclose(rebased.update(boxes, scores), want, atol=1e-15)
    assert gated.threshold_quantile() == 0.0 == rebased.threshold_quantile()


def test_persistent_quantiles_cut_the_clutter_a_lower_threshold_adds():
    """The same scene as a detector run at a lower threshold would give it: as many
    false detections again, scored below every true one and never found again. ``u*``
    lands at the clutter's share of the scores (within four binomial standard errors
    plus the 20 bins' half-width) and the clutter maps to 0. Gated, a true detection
    keeps its plain quantile among all the scores; rebased, it reads its quantile among
    the true detections alone (within the same tolerance) — what the plain quantile
    gave it before the clutter came. A 95 % test on the cut changes none of it: the
    clutter is found again far below the gate's level."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles
    from pgm.factors.scores import mid_ranks

    rng = np.random.default_rng(12)
    scene = persistent_scene(rng, frames=200, pi_false=0.0)
    frames = []
    for boxes, scores, _ in scene:
        k = len(scores)
        fb = np.column_stack([rng.uniform(0, 1000, (k, 2)), np.full((k, 2), [40.0, 100.0])])
        fs = scores.min() - 10.0 - rng.uniform(0, 5, k)  # below every true score
        frames.append((np.concatenate([boxes, fb]), np.concatenate([scores, fs]), k))
    share = 0.5  # as many false detections as true ones
    n = sum(k for *_, k in frames) * 2
    tol = 4 * np.sqrt(share * (1 - share) / n) + 0.5 / 20
    for rebase, confidence in ((False, None), (True, None), (True, 0.95)):
        pq = PersistentQuantiles(rebase=rebase, confidence=confidence)
        got = [pq.update(b, s) for b, s, _ in frames]
        assert abs(pq.threshold_quantile() - share) < tol
        is_true = np.concatenate([np.arange(len(s)) < k for _, s, k in frames[-50:]])
        q = np.concatenate(got[-50:])
        assert np.all(q[~is_true] == 0.0)
        b, s, k = frames[-1]
        if rebase:  # the quantile among the true detections seen so far
            seen = np.sort(np.concatenate([x[:kk] for _, x, kk in frames]))
            np.testing.assert_allclose(got[-1][:k], mid_ranks(seen, s[:k]), atol=2 * tol)
            kept = q >= 0.2  # about 80 % of the true detections, none of the clutter
            assert abs(kept[is_true].mean() - 0.8) < 2 * tol
        else:  # the plain quantile among every score
            seen = np.sort(np.concatenate([x for _, x, _ in frames]))
            np.testing.assert_allclose(got[-1][:k], mid_ranks(seen, s[:k]), atol=1e-12)
            assert np.all(q[is_true] > 0.2)  # every true one above the lowest fifth
        assert not (q >= 0.2)[~is_true].any()


def test_persistent_quantiles_are_invariant_to_the_detectors_scale():
    """Fed the same detections with scores through any strictly increasing map, both
    maps give the same values, exactly; a floor outside [0, 1] is an error."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    scene = persistent_scene(np.random.default_rng(13), frames=60)
    all_scores = np.concatenate([s for _, s, _ in scene]) * 20 + 40
    split = np.cumsum([len(s) for _, s, _ in scene])[:-1]
    for rebase, confidence in ((False, None), (True, None), (True, 0.95)):
        ref = None
        for name, f in [("none", lambda s: s)] + list(MAPS.items()):
            m = PersistentQuantiles(rebase=rebase, confidence=confidence)
            q = np.concatenate([m.update(b, s) for (b, _, _), s in
                                zip(scene, np.split(f(all_scores), split), strict=True)])
            if ref is None:
                ref = q
            np.testing.assert_array_equal(q, ref, err_msg=name)
        assert m.threshold_quantile() > 0  # this scene's clutter is seen: the gate acts
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="floor"):
            PersistentQuantiles(floor=bad)


def test_the_chance_level_is_the_rate_a_false_box_near_people_is_found_again():
    """A crowd whose false detections land two box sizes from a person (where a lower
    threshold's clutter lands) and are scored below every true one: many of them are
    "found again" by a neighbour's box. Oracle: the chance level measured from the moved
    copies of the boxes equals the rate at which the false detections are found again
    (the model's own labels against the scene's truth), within four binomial standard
    errors; the raw curve puts the clutter above one half of the top rate — no gate — and
    the curve above chance gates it at its share of the scores."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    rng = np.random.default_rng(21)
    pos = rng.uniform(0, 500, (40, 2))
    vel = rng.normal(0, 2, (40, 2))
    pq, truth, found = PersistentQuantiles(), [], []
    for _ in range(250):
        pos = pos + vel
        tb = np.column_stack([pos, np.full((40, 2), [40.0, 100.0])])
        k = len(tb)
        src = tb[rng.integers(0, k, k)]
        step = np.array([[2, 0], [-2, 0], [0, 2], [0, -2]], float)[rng.integers(0, 4, k)]
        fb = np.column_stack([src[:, :2] + step * src[:, 2:], src[:, 2:]])
        scores = np.r_[rng.normal(5, 1, k), rng.normal(-5, 1, k)]
        pq.update(np.concatenate([tb, fb]), scores)
        found.append(pq.model.last_labelled[1])
        truth.append(np.r_[np.ones(k, bool), np.zeros(k, bool)])
    labelled = np.concatenate(truth[:-1])
    false_rate = np.concatenate(found)[~labelled].mean()
    n = (~labelled).sum()
    assert false_rate > 0.3  # a crowd: false boxes are often found again
    se = np.sqrt(false_rate * (1 - false_rate) / min(n, pq.chance_labelled))
    assert abs(pq.chance() - false_rate) < 4 * se
    raw = pq.model.curve / pq.model.curve[-1]
    assert raw[0] >= 0.5  # the raw curve sees no clutter...
    tol = 4 * np.sqrt(0.25 / (2 * labelled.size)) + 0.5 / pq.model.bins
    assert abs(pq.threshold_quantile() - 0.5) < tol  # ... the curve above chance does


def _gate_with_labels(per_bin: int, rates: np.ndarray, chance: float, copies: int,
                      confidence: float | None):
    """A gate whose model holds ``per_bin`` labelled scores in each of its bins, the
    first ``round(rate · per_bin)`` of each found again, and a chance level measured on
    ``copies`` moved copies."""
    from pgm.factors.persistent_quantiles import PersistentQuantiles

    pq = PersistentQuantiles(confidence=confidence)
    bins = pq.model.bins
    assert rates.size == bins
    scores = np.arange(bins * per_bin, dtype=float)
    found = np.concatenate([np.arange(per_bin) < round(r * per_bin) for r in rates])
    pq.model.seen.add(scores)
    pq.model.add_labels(scores, found)
    pq.chance_found, pq.chance_labelled = round(chance * (copies + 1)), copies
    return pq


def test_the_clutter_gate_cuts_only_what_the_labels_show_with_the_confidence():
    """Oracle, the one-sided test by hand: the two lowest of 20 bins found again at 0.77,
    the rest at 0.99, the chance level 0.62 (a crowd) — the gate's level about 0.805.
    With 30 labels a bin the two bins' shortfall is under one of its standard errors:
    the point estimate cuts them, a 95 % test does not. With 3 000 a bin it is over six,
    and the test cuts exactly what the point estimate does. Far below the level (a lower
    threshold's clutter, found again at chance) 30 labels a bin suffice; found short only
    in part, the cut goes as far as the evidence does."""

    def z(pq, rates, per_bin, k):
        """The shortfall of bins [0, k) below the gate's level, in standard errors."""
        top, rho = float(pq.model.curve[-1]), pq.chance()
        n, h = per_bin * k, sum(round(x * per_bin) for x in rates[:k])
        r = (h + 0.5) / (n + 1)
        mid = rho + 0.5 * (top - rho)
        return (mid - r) / np.sqrt(r * (1 - r) / (n + 1) + 0.25 * rho * (1 - rho) / 4000
                                   + 0.25 * top * (1 - top) / per_bin)

    rates = np.r_[0.77, 0.77, np.full(18, 0.99)]
    for per_bin, cut in ((30, False), (3000, True)):
        point = _gate_with_labels(per_bin, rates, 0.62, 4000, None).threshold_quantile()
        assert 0.05 < point < 0.15
        pq = _gate_with_labels(per_bin, rates, 0.62, 4000, 0.95)
        assert (z(pq, rates, per_bin, 2) >= 1.645) == cut
        assert pq.threshold_quantile() == (point if cut else 0.0)
    clutter = np.r_[np.full(4, 0.62), np.full(16, 0.99)]
    tested = _gate_with_labels(30, clutter, 0.62, 4000, 0.95).threshold_quantile()
    assert tested == _gate_with_labels(30, clutter, 0.62, 4000, None).threshold_quantile() > 0.15
    # in part: the edge of the largest group of bins from the bottom (of those below the
    # point estimate's u*) whose shortfall is 1.645 errors or more
    mixed = np.r_[0.70, 0.70, np.full(12, 0.77), np.full(6, 0.99)]
    point = _gate_with_labels(30, mixed, 0.62, 4000, None).threshold_quantile()
    pq = _gate_with_labels(30, mixed, 0.62, 4000, 0.95)
    tested = pq.threshold_quantile()
    k, below = round(tested * 20), int(np.ceil(point * 20 - 0.5))
    assert 0 < tested < point and tested == k / 20
    assert z(pq, mixed, 30, k) >= 1.645
    assert all(z(pq, mixed, 30, j) < 1.645 for j in range(k + 1, below + 1))
    for bad in (0.4, 1.0, float("nan")):
        with pytest.raises(ValueError, match="confidence"):
            _gate_with_labels(30, rates, 0.62, 4000, bad)
