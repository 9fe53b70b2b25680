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
