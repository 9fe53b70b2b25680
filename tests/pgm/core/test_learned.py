"""A factor's learned state: typed, kept apart from its declaration, one per learner (a
single graph's engine, each replica of a plate, each track of an association) without
copying the factor."""

from __future__ import annotations

import ast
import inspect
import textwrap
from dataclasses import dataclass

import numpy as np
import pytest

from pgm import FactorGraph, Plate
from pgm.core.factor import Factor, find_names, registered_factor_types
from pgm.core.frame import FrameContext
from pgm.core.learned import LearnedState, StateField
from pgm.factors import LikelihoodFactor
from pgm.factors.gaussian import GaussianPrior
from pgm.inference import Engine
from pgm.models import colour_pf
from pgm.observation.appearance.base import TemplateState
from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood
from pgm.synthetic.scenes import multi_target_scene


@pytest.fixture(scope="module")
def scene():
    return multi_target_scene(seed=3, n_frames=8, n_objects=2, occluder=False)


def _box(scene, obj: int, frame: int = 1) -> np.ndarray:
    x, y, w, h = scene.box(obj, frame)
    return np.array([x + w / 2, y + h / 2, w, h])


def test_fields_read_and_write_the_bound_state():
    f = ColourHistogramLikelihood("x")
    assert isinstance(type(f).__dict__.get("template") or ColourHistogramLikelihood.template,
                      StateField)
    assert isinstance(f.state, TemplateState) and f.template is None
    f.template = np.ones(3)
    assert f.state.template is f.template
    other = f.fresh_state()
    view = f.bind(other)
    assert view.template is not f.template  # a copy, not the same array
    np.testing.assert_array_equal(view.template, f.template)
    view.template = np.zeros(3)  # learning through the view changes only its state
    np.testing.assert_array_equal(f.template, np.ones(3))
    assert view.state is other and other.template is view.template
    # the declaration is shared, not copied
    assert view.scorer is f.scorer and view.name == f.name
    assert f.bind(f.state) == f and f.bind(f.state).template is f.template


def test_bind_refuses_another_state_and_factors_without_state_bind_to_themselves():
    f = ColourHistogramLikelihood("x")

    @dataclass
    class Other(LearnedState):
        template: object = None

    with pytest.raises(ValueError, match="TemplateState"):
        f.bind(Other())
    g = GaussianPrior("x", mean=[0.0], cov=[[1.0]])
    assert g.state is None and g.fresh_state() is None and g.bind(None) is g


def test_state_declarations_are_checked():
    with pytest.raises(ValueError, match="@dataclass deriving from"):
        class Bad(LikelihoodFactor):  # noqa: F841
            State = dict

    @dataclass
    class NoDefault(LearnedState):
        template: object

    with pytest.raises(ValueError, match="needs a default"):
        class Bad2(LikelihoodFactor):  # noqa: F841
            State = NoDefault

    @dataclass
    class Hides(LearnedState):
        log_likelihood: object = None

    with pytest.raises(ValueError, match="hides the class attribute"):
        class Bad3(LikelihoodFactor):  # noqa: F841
            State = Hides


def _learns(cls: type[Factor]) -> bool:
    """Whether a class learns from the video: it updates after frames, or learns a model
    in the first frame."""
    if cls.update is not Factor.update:
        return True
    return issubclass(cls, LikelihoodFactor) and (
        cls.initialize is not LikelihoodFactor.initialize or hasattr(cls, "learn"))


def test_every_toolkit_factor_that_learns_declares_its_state():
    """Each of the toolkit's factor classes that learns keeps what it learns in a typed
    State; and no method of any factor assigns an attribute outside it after the factor
    is built (an assignment ``self.x = `` in a method other than ``__init__`` names a
    State field): what changes as the video runs is the state's, never the factor's."""
    find_names(lambda: False)  # every toolkit module that defines factors, imported
    missing, outside = [], []
    for name, cls in registered_factor_types().items():
        if not cls.__module__.startswith(("pgm.", "models.", "inference.")) or \
                inspect.isabstract(cls):
            continue
        if _learns(cls) and cls.State is None:
            missing.append(name)
        fields = {n for n in dir(cls) if isinstance(getattr(cls, n, None), StateField)}
        for klass in cls.__mro__:
            if klass in (Factor, object) or not klass.__module__.startswith("pgm"):
                continue
            try:
                tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
            except (OSError, TypeError, SyntaxError):
                continue
            for fn in ast.walk(tree):
                # __init__ builds the declaration, check() completes it against the graph
                if not isinstance(fn, ast.FunctionDef) or fn.name in ("__init__", "check"):
                    continue
                for node in ast.walk(fn):
                    targets = node.targets if isinstance(node, ast.Assign) else \
                        [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
                    for t in targets:
                        for el in (t.elts if isinstance(t, ast.Tuple) else [t]):
                            if (isinstance(el, ast.Attribute) and isinstance(el.value, ast.Name)
                                    and el.value.id == "self" and el.attr not in fields):
                                outside.append(f"{name}.{fn.name}: self.{el.attr}")
    assert not missing, f"factors that learn without a State: {missing}"
    assert not outside, f"assignments outside the State: {sorted(set(outside))}"


def _colour_plate(scene) -> FactorGraph:
    t = colour_pf.build_graph(colour_pf.Params(init_box=tuple(_box(scene, 0)), num_particles=30,
                                               appearance="colour"))
    return FactorGraph(list(t.variables.values()), list(t.factors.values()), name="pf",
                       meta=t.meta, plates=[Plate("target", tuple(t.variables))])


def test_plate_replicas_learn_into_their_own_state_without_copying_factors(scene, monkeypatch):
    g = _colour_plate(scene)
    eng = Engine(g, np.random.default_rng(0), num_particles=30)
    name = next(f.name for f in g.factors.values() if isinstance(f, ColourHistogramLikelihood))

    def refuse(self, memo):
        raise AssertionError(f"factor {self.name!r} deep-copied while stepping")

    monkeypatch.setattr(Factor, "__deepcopy__", refuse, raising=False)
    ctx = FrameContext(1, scene.frames[0])
    eng.add(np.array([_box(scene, 0), _box(scene, 1)]), ctx)
    for f in range(2, 5):
        eng.step(FrameContext(f, scene.frames[f - 1]), lifecycle=False)
    a, b = eng.factor(name, 0), eng.factor(name, 1)
    assert a is not b and a.scorer is b.scorer  # views of one declaration
    assert a.state is eng.replicas.state[0].find(name, TemplateState)
    assert b.state is eng.replicas.state[1].find(name, TemplateState)
    assert a.template is not None and not np.array_equal(a.template, b.template)
    assert eng.factor(name).template is None  # the declared factor learned nothing


def test_one_graph_keeps_its_factors_state_in_the_engine_slots(scene):
    t = colour_pf.build_graph(colour_pf.Params(init_box=tuple(_box(scene, 0)), num_particles=30,
                                               appearance="colour"))
    eng = Engine(t, np.random.default_rng(0))
    name = next(f.name for f in t.factors.values() if isinstance(f, ColourHistogramLikelihood))
    eng.step(FrameContext(1, scene.frames[0]))
    slot = eng.state.find(name, TemplateState)
    assert slot is eng.factor(name).state and slot.template is not None
    assert t.factors[name].template is None  # the user's graph is not touched


def test_a_plate_refuses_a_learning_factor_without_state(scene):
    class Learner(LikelihoodFactor):
        abstract = True  # not registered

        def log_likelihood(self, x, ctx):
            return np.zeros(len(x))

        def update(self, estimates, scores, frame=None):
            self.seen = True

    g = _colour_plate(scene)
    g2 = FactorGraph(list(g.variables.values()),
                     list(g.factors.values()) + [Learner("object", name="learner")], name="pf",
                     meta=g.meta, plates=g.plates)
    with pytest.raises(ValueError, match="declares no State"):
        Engine(g2, np.random.default_rng(0))
