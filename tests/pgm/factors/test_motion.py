"""The motion library (pgm.factors.motion): exact discretisation against the closed forms,
constants in seconds that carry between frame rates, and each model run by the engine
equal to the Kalman filter (Gaussian beliefs), within Monte-Carlo error with particles,
and inside a plate."""

import numpy as np
import pytest

import pgm
from pgm.core.expfam import Gaussian
from pgm.factors.motion import (
    MOTION_MODELS,
    MotionTransition,
    constant_acceleration,
    constant_velocity,
    coordinated_turn,
    discretize,
    random_walk,
    singer,
)
from pgm.inference import Engine, kalman_filter

LABELS = ("x", "y", "vx", "vy", "ax", "ay")


def _models(fps=10.0):
    """One transition of each model on the six-component layout above."""
    return {
        "random-walk": random_walk("s", labels=LABELS, axes=[("x",), ("y",)], q=2.0,
                                   fps=fps, q_static=0.5),
        "constant-velocity": constant_velocity("s", labels=LABELS,
                                               axes=[("x", "vx"), ("y", "vy")], q=3.0, fps=fps),
        "constant-acceleration": constant_acceleration(
            "s", labels=LABELS, axes=[("x", "vx", "ax"), ("y", "vy", "ay")], q=1.5, fps=fps),
        "singer": singer("s", labels=LABELS, axes=[("x", "vx", "ax"), ("y", "vy", "ay")],
                         sigma=2.0, tau=0.8, fps=fps),
        "coordinated-turn": coordinated_turn("s", labels=LABELS,
                                             axes=[("x", "vx"), ("y", "vy")],
                                             turn_rate=0.6, q=1.0, fps=fps, q_static=0.1),
    }


def test_the_discretisation_is_the_closed_form():
    dt, q = 0.1, 3.0
    F, Q = discretize(np.array([[0.0, 1.0], [0.0, 0.0]]), np.diag([0.0, q]), dt)
    np.testing.assert_allclose(F, [[1, dt], [0, 1]], atol=1e-14)
    np.testing.assert_allclose(Q, q * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]]),
                               rtol=1e-10)
    F, Q = discretize(np.diag([1.0, 1.0], k=1), np.diag([0.0, 0.0, q]), dt)
    np.testing.assert_allclose(F, [[1, dt, dt ** 2 / 2], [0, 1, dt], [0, 0, 1]], atol=1e-14)
    np.testing.assert_allclose(Q, q * np.array([[dt ** 5 / 20, dt ** 4 / 8, dt ** 3 / 6],
                                                [dt ** 4 / 8, dt ** 3 / 3, dt ** 2 / 2],
                                                [dt ** 3 / 6, dt ** 2 / 2, dt]]), rtol=1e-9)
    s = _models()["singer"]
    a = np.exp(-dt / 0.8)  # the acceleration decays as an Ornstein-Uhlenbeck process
    assert s.F[4, 4] == pytest.approx(a, rel=1e-12)
    assert s.Q[4, 4] == pytest.approx(4.0 * (1 - a ** 2), rel=1e-9)
    ct = _models()["coordinated-turn"]
    w = 0.6 * dt  # the velocity rotates by the turn rate
    np.testing.assert_allclose(ct.F[np.ix_([2, 3], [2, 3])],
                               [[np.cos(w), -np.sin(w)], [np.sin(w), np.cos(w)]], atol=1e-12)


@pytest.mark.parametrize("model", list(MOTION_MODELS))
def test_constants_in_seconds_carry_between_frame_rates(model):
    """One second at 30 frames/s is one second at 10: the discretisation composes."""
    def one_second(f: MotionTransition, steps: int):
        F, Q = np.eye(6), np.zeros((6, 6))  # noqa: N806
        for _ in range(steps):
            F, Q = f.F @ F, f.F @ Q @ f.F.T + f.Q  # noqa: N806
        return F, Q

    f10, q10 = one_second(_models(10.0)[model], 10)
    f30, q30 = one_second(_models(30.0)[model], 30)
    np.testing.assert_allclose(f30, f10, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(q30, q10, rtol=1e-8, atol=1e-12)


def _graph(f: MotionTransition) -> pgm.FactorGraph:
    H = np.zeros((2, 6))  # noqa: N806
    H[0, 0] = H[1, 1] = 1.0
    return pgm.FactorGraph(
        [pgm.Variable("s", 6, role="state", labels=LABELS)],
        [pgm.GaussianPrior("s", mean=np.zeros(6), cov=np.diag([4, 4, 1, 1, 0.5, 0.5])),
         f, pgm.LinearGaussianLikelihood("s", H=H, R=np.eye(2) * 0.5)], name="motion")


def _measurements(T=25, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(T) / 10.0
    return np.stack([3 * np.sin(t), 2 * t], axis=1) + rng.normal(0, 0.7, (T, 2))


@pytest.mark.parametrize("model", list(MOTION_MODELS))
def test_each_model_is_the_kalman_filter_with_gaussian_beliefs(model):
    f = _models()[model]
    g = _graph(f)
    ys = _measurements()
    eng = Engine(g, 0, belief_types={"s": Gaussian})
    got = np.array([eng.step(pgm.FrameContext(t + 1, measurements=y)).estimates["s"]
                    for t, y in enumerate(ys)])
    kf = kalman_filter(np.zeros(6), np.diag([4, 4, 1, 1, 0.5, 0.5]), f.F, f.Q,
                       g.factors_of("s", "likelihood")[0].H, np.eye(2) * 0.5, ys)
    np.testing.assert_allclose(got, kf.filtered_means, rtol=1e-9, atol=1e-9)


def test_particles_follow_the_kalman_filter_within_monte_carlo_error():
    """The particle filter's means over R independent runs against the Kalman filter's:
    each difference in units of its Monte-Carlo standard error (from the runs' spread)
    is ~ Student-t with R - 1 = 7 degrees of freedom: E[z²] = 7/5 and sd(z²) = 2.8, so
    even if all 100 differences were one (they are correlated over time), the mean z²
    stays below 1.4 + 3 x 2.8 ≈ 10 but for a 3-sd event; a filter of the wrong model or a
    biased weight is at hundreds."""
    f = _models()["constant-velocity"]
    g = _graph(f)
    ys = _measurements()
    runs = []
    for seed in range(8):
        eng = Engine(g, seed, num_particles=1000)
        runs.append([eng.step(pgm.FrameContext(t + 1, measurements=y)).estimates["s"][:4]
                     for t, y in enumerate(ys)])
    runs = np.array(runs)  # (R, T, 4)
    kf = kalman_filter(np.zeros(6), np.diag([4, 4, 1, 1, 0.5, 0.5]), f.F, f.Q,
                       g.factors_of("s", "likelihood")[0].H, np.eye(2) * 0.5, ys)
    se = runs.std(axis=0, ddof=1) / np.sqrt(len(runs))
    z = (runs.mean(axis=0) - kf.filtered_means[:, :4]) / se
    assert np.mean(z ** 2) < 10.0, np.mean(z ** 2)


def test_a_saved_motion_model_keeps_its_physical_constants():
    f = _models()["singer"]
    g = _graph(f)
    back = pgm.FactorGraph.from_dict(g.to_dict())
    h = back.factors[f.name]
    assert isinstance(h, MotionTransition) and h.params() == f.params()
    assert h.params()["tau"] == 0.8 and "F" not in h.params()
    np.testing.assert_array_equal(h.Q, f.Q)


def test_a_motion_model_in_a_plate_is_the_single_graph_run():
    f = _models()["coordinated-turn"]
    g = _graph(f)
    plated = pgm.FactorGraph(list(g.variables.values()), list(g.factors.values()),
                             name="motion", plates=[pgm.Plate("target", ("s",))])
    ys = _measurements(10)
    frames = [pgm.FrameContext(t + 1, measurements=y) for t, y in enumerate(ys)]
    single = Engine(g, 0, num_particles=300)
    plate = Engine(plated, 0, num_particles=300)
    single.step(frames[0])
    plate.add(None, frames[0], rngs=[np.random.default_rng(0)], count=1)
    single = Engine(g, np.random.default_rng(0), num_particles=300)
    single.step(frames[0])
    for fr in frames[1:]:
        single.step(fr)
        plate.step(fr, lifecycle=False)
    np.testing.assert_array_equal(plate.beliefs["s"].x[0], single.beliefs["s"].x)


def test_bad_motion_declarations_are_one_line_errors():
    with pytest.raises(ValueError, match="unknown motion model"):
        MotionTransition("s", model="zigzag", labels=LABELS, axes=[("x",)], fps=10)
    with pytest.raises(ValueError, match="components"):
        constant_velocity("s", labels=LABELS, axes=[("x", "nope")], q=1.0, fps=10)
    with pytest.raises(ValueError, match="position first"):
        constant_velocity("s", labels=LABELS, axes=[("x",)], q=1.0, fps=10)
    with pytest.raises(ValueError, match="two axes"):
        coordinated_turn("s", labels=LABELS, axes=[("x", "vx")], turn_rate=1.0, q=1.0, fps=10)
    with pytest.raises(ValueError, match="positive"):
        random_walk("s", labels=LABELS, axes=[("x",)], q=1.0, fps=0)
    with pytest.raises(ValueError, match="finite"):
        random_walk("s", labels=LABELS, axes=[("x",)], q=float("nan"), fps=10)


def test_a_motion_laid_out_over_other_labels_than_the_variables_is_refused():
    """Labels in another order than the variable's would move other components (the
    velocity of x applied to y): the graph refuses it, naming both orders; the variable's
    own order is accepted, and so is a variable without labels (dimension checked)."""
    own, shuffled = ("x", "vx", "y", "vy"), ("x", "y", "vx", "vy")
    axes = [("x", "vx"), ("y", "vy")]

    def graph(labels, motion_labels):
        return pgm.FactorGraph(
            [pgm.Variable("s", 4, labels=labels)],
            [pgm.GaussianPrior("s", mean=np.zeros(4), cov=1.0),
             constant_velocity("s", labels=motion_labels, axes=axes, q=1.0, fps=10)])

    with pytest.raises(ValueError, match=r"labels \['x', 'y', 'vx', 'vy'\] but variable 's'"):
        graph(own, shuffled)
    graph(None, shuffled)
    graph(own, own)
