"""The engine's typed settings: checked when made, saved whole, read back equal; unknown
keys and bad values are one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from pgm.core.beliefs import Particles
from pgm.inference.settings import EngineSettings, register_belief_form


def test_settings_round_trip_through_a_saved_model():
    s = EngineSettings(num_particles={"x": 50}, resampling="stratified", ess_threshold=0.25,
                       fusion="product", beliefs={"x": "particles"})
    back = EngineSettings.from_dict(s.to_dict(full=True))
    assert back == s and back.belief_classes() == {"x": Particles}
    assert EngineSettings.from_dict(None) == EngineSettings()
    assert s.replace(ess_threshold=None) == s and s.replace(ess_threshold=1.0).ess_threshold == 1


@pytest.mark.parametrize("kwargs, message", [
    ({"num_particles": 0}, "num_particles"),
    ({"num_particles": {"x": 2.5}}, "num_particles"),
    ({"ess_threshold": np.nan}, "ess_threshold"),
    ({"ess_threshold": 1.5}, "ess_threshold"),
    ({"ess_threshold": "abc"}, "ess_threshold must be in"),
    ({"inframe_iterations": -1}, "inframe_iterations"),
    ({"fusion": "sum"}, "fusion"),
    ({"message_weight": "both"}, "message_weight"),
    ({"beliefs": {"x": "histogram"}}, "beliefs"),
])
def test_bad_settings_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        EngineSettings(**kwargs)


def test_unknown_keys_of_a_saved_model_are_refused():
    with pytest.raises(ValueError, match="particels"):
        EngineSettings.from_dict({"particels": 10})


def test_a_belief_form_of_ones_own_is_named_in_saved_settings():
    class Grid(Particles):
        pass

    register_belief_form("test-grid", Grid)
    assert EngineSettings(beliefs={"x": "test-grid"}).belief_classes() == {"x": Grid}


def test_belief_classes_given_to_the_engine_are_saved_with_the_model():
    """``Engine(belief_types={"x": Gaussian})`` runs the exact rules; the saved model
    names the form, so that the model reloaded (no ``belief_types``) holds the same belief
    and gives the same estimates. A class of no registered form is not named."""
    import pgm
    from pgm.core.expfam import Gaussian
    from pgm.inference import Engine
    from pgm.models import linear_gaussian

    graph = linear_gaussian.build_graph(linear_gaussian.Params())
    engine = Engine(graph, 0, belief_types={"x": Gaussian})
    assert engine.graph.meta["engine"]["beliefs"] == {"x": "gaussian"}
    reloaded = Engine(pgm.FactorGraph.from_dict(engine.graph.to_dict()), 0)
    assert reloaded.belief_type("x") is Gaussian
    z = np.random.default_rng(3).normal(size=(5, 1))
    for t, zt in enumerate(z):
        a = engine.step(pgm.FrameContext(t + 1, measurements=zt)).estimates["x"]
        b = reloaded.step(pgm.FrameContext(t + 1, measurements=zt)).estimates["x"]
        np.testing.assert_array_equal(a, b)

    class Unnamed(Particles):
        pass

    assert EngineSettings().with_beliefs({"x": Unnamed}) == EngineSettings()
