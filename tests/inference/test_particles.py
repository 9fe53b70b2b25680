"""The particle rules: resampling when the ESS says so (and reporting it, typed), the
mass kept; a transition's draw of the wrong shape named."""

from __future__ import annotations

import numpy as np
import pytest

from pgm import FactorGraph, Variable
from pgm.core.frame import FrameContext
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.inference import Engine
from pgm.inference.info import VariableInfo


def _graph(transition=None):
    return FactorGraph(
        [Variable("x", 1, role="state")],
        [GaussianPrior("x", mean=[0.0], cov=4.0),
         transition or LinearGaussianTransition("x", F=[[1.0]], Q=[[0.5]]),
         LinearGaussianLikelihood("x", H=[[1.0]], R=[[0.25]])], name="walk")


@pytest.mark.parametrize("threshold, resampled", [(1.0, True), (0.0, False)])
def test_resampling_follows_the_ess_threshold_and_is_reported(threshold, resampled):
    eng = Engine(_graph(), np.random.default_rng(0), num_particles=200,
                 ess_threshold=threshold)
    for t in range(1, 4):
        rec = eng.step(FrameContext(t, measurements=np.array([0.3 * t])))
        info = rec.info["x"]
        assert isinstance(info, VariableInfo) and info.resampled is resampled
        assert rec.resampled["x"] is resampled and 0 < info.ess <= 200
        assert eng.beliefs["x"].log_mass == pytest.approx(0.0, abs=1e-9)
        if resampled:  # equal weights after resampling
            np.testing.assert_allclose(eng.beliefs["x"].weights, 1 / 200)


def test_a_transition_drawing_the_wrong_shape_is_named():
    class Bad(LinearGaussianTransition):
        abstract = True

        def sample(self, rng, x, *past):
            return x[:, :0]

    eng = Engine(_graph(Bad("x", F=[[1.0]], Q=[[0.5]], name="bad")), np.random.default_rng(0),
                 num_particles=20)
    eng.step(FrameContext(1, measurements=np.array([0.0])))
    with pytest.raises(ValueError, match="factor 'bad': sample"):
        eng.step(FrameContext(2, measurements=np.array([0.0])))


@pytest.mark.parametrize("belief", ["particles", "gaussian"])
@pytest.mark.parametrize("z, needle", [(np.array([np.nan]), "is not finite ([nan])"),
                                       (np.array([1.0, 2.0]), "has 2 components where H has 1")])
def test_a_measurement_that_cannot_be_read_is_named(belief, z, needle):
    """A measurement of the wrong length or with NaN (the reference ``kalman_filter`` reads
    a NaN row as missing; the engine's missing frame is ``measurements=None``): a
    ``ValueError`` naming the factor and the frame, on particles and on the exact rule."""
    from pgm.core.expfam import Gaussian

    graph = FactorGraph([Variable("x", 1, role="state")],
                        [GaussianPrior("x", mean=[0.0], cov=1.0),
                         LinearGaussianTransition("x", F=np.eye(1), Q=0.1 * np.eye(1)),
                         LinearGaussianLikelihood("x", H=np.eye(1), R=np.eye(1), name="z")])
    engine = Engine(graph, 0, num_particles=50,
                    belief_types={"x": Gaussian} if belief == "gaussian" else None)
    engine.step(FrameContext(1, measurements=np.array([0.5])))
    engine.step(FrameContext(2, measurements=None))  # a frame without one
    with pytest.raises(ValueError, match=r"factor 'z': the measurement of frame 3 ") as err:
        engine.step(FrameContext(3, measurements=z))
    assert needle in str(err.value) and "measurements=None" in str(err.value)


@pytest.mark.parametrize("belief", ["particles", "gaussian"])
def test_a_vb_noise_factor_naming_no_likelihood_of_its_target_says_what_there_is(belief):
    """``VBNoise(likelihood=...)`` misspelled: the run's error names what it asked for and
    the likelihoods its target has."""
    from pgm.core.expfam import Gaussian
    from pgm.factors.multitarget import InverseGammaPrior, VBNoise

    graph = FactorGraph([Variable("x", 1, role="state"), Variable("noise", 1, role="noise")],
                        [GaussianPrior("x", mean=[0.0], cov=1.0),
                         LinearGaussianTransition("x", F=np.eye(1), Q=np.eye(1)),
                         LinearGaussianLikelihood("x", H=np.eye(1), R=np.eye(1), name="lik"),
                         InverseGammaPrior("noise", sigma=[1.0], alpha=2.0),
                         VBNoise("noise", "x", likelihood="likk", name="vb")])
    engine = Engine(graph, 0, num_particles=20,
                    belief_types={"x": Gaussian} if belief == "gaussian" else None)
    with pytest.raises(ValueError, match=r"'vb': needs one likelihood on 'x' named 'likk'; "
                                         r"'x' has \['lik'\]"):
        engine.step(FrameContext(1, measurements=np.array([0.3])))
