"""Rules travel with their model: a factor class declares its rule where it is defined;
an engine records which rule serves each factor (``graph.meta["rules"]``, by importable
name), a reloaded model runs with those rules and reproduces the run that saved it; a
rule that cannot be found is a one-line error naming it, never a run with another rule;
``pgm graph/track --import MODULE_OR_FILE`` loads a user's factors and rules."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_run import run_cli

from pgm import FactorGraph, Plate
from pgm.core.beliefs import Particles
from pgm.core.frame import FrameContext
from pgm.factors import LikelihoodFactor, LinearGaussianLikelihood
from pgm.inference import DEFAULT_RULES, Engine
from pgm.inference.rules import PER_REPLICA, declare, rule_name, use_rules
from pgm.models import linear_gaussian


def tempered(ctx, factor, frame):
    """A user's rule for a built-in factor: the likelihood at a quarter of its strength."""
    return 0.25 * factor.log_likelihood(ctx.beliefs[factor.variables[0]].x, frame)


class TravelPull(LikelihoodFactor):
    """A user's factor: pulls the first component towards ``target``."""

    def __init__(self, variable, *, target, name=None):
        super().__init__(variable, name=name)
        self.target = float(target)

    def params(self):
        return {"target": self.target}

    def log_likelihood(self, x, ctx):
        raise AssertionError("its declared rule, not log_likelihood, must run")


@declare(TravelPull, Particles)
def pull_rule(ctx, factor, frame):
    return -0.5 * (ctx.beliefs[factor.variables[0]].x[:, 0] - factor.target) ** 2


def _frames(n=8):
    rng = np.random.default_rng(1)
    return [FrameContext(t + 1, measurements=rng.normal(0.2 * t, 0.7, 1)) for t in range(n)]


def _estimates(engine, frames):
    return np.array([engine.step(f).estimates["x"] for f in frames])


def _reloaded(graph: FactorGraph) -> FactorGraph:
    return FactorGraph.from_dict(json.loads(json.dumps(graph.to_dict())))


def _lik(graph):
    return next(f.name for f in graph.factors.values() if isinstance(f, LinearGaussianLikelihood))


def _plated(graph: FactorGraph) -> FactorGraph:
    return FactorGraph(list(graph.variables.values()), list(graph.factors.values()),
                       name=graph.name, meta=graph.meta,
                       plates=[Plate("target", tuple(graph.variables))])


def test_a_custom_rule_on_a_built_in_factor_is_saved_and_reloaded():
    g = linear_gaussian.build_graph(linear_gaussian.Params())
    rules = DEFAULT_RULES.copy()
    rules.register(LinearGaussianLikelihood, Particles)(tempered)
    engine = Engine(g, 0, rules=rules, num_particles=300)
    first = _estimates(engine, _frames())
    lik = _lik(g)
    assert engine.graph.meta["rules"][lik] == f"{__name__}:tempered"
    others = {n: r for n, r in engine.graph.meta["rules"].items() if n != lik}
    assert others and all(r.startswith("pgm.inference.") for r in others.values())
    again = _estimates(Engine(_reloaded(engine.graph), 0, num_particles=300), _frames())
    np.testing.assert_array_equal(again, first)  # the reloaded model, the same run
    default = _estimates(Engine(g, 0, num_particles=300), _frames())
    assert np.abs(default - first).max() > 1e-3  # the rule matters: another one differs


def test_a_model_config_attaches_a_rule_to_its_graph():
    """What a model config's ``build`` does to run a factor with a rule of its own."""
    g = linear_gaussian.build_graph(linear_gaussian.Params())
    lik = _lik(g)
    use_rules(g, {lik: tempered})
    assert g.meta["rules"] == {lik: f"{__name__}:tempered"}
    rules = DEFAULT_RULES.copy()
    rules.register(LinearGaussianLikelihood, Particles)(tempered)
    np.testing.assert_array_equal(_estimates(Engine(g, 0, num_particles=300), _frames()),
                                  _estimates(Engine(g, 0, rules=rules, num_particles=300),
                                             _frames()))
    with pytest.raises(ValueError, match="no factor"):
        use_rules(g, {"nope": tempered})

    def local(ctx, factor, frame):
        return None

    with pytest.raises(ValueError, match="inside a function"):
        use_rules(g, {lik: local})


def test_a_users_factor_carries_its_declared_rule():
    g = linear_gaussian.build_graph(linear_gaussian.Params()).with_factors(
        TravelPull("x", target=3.0, name="pull"))
    engine = Engine(g, 0, num_particles=300)  # no table given: the class's own rule
    first = _estimates(engine, _frames())
    assert engine.graph.meta["rules"]["pull"] == f"{__name__}:pull_rule"
    assert first[-1, 0] > 1.0  # pulled towards 3
    again = _estimates(Engine(_reloaded(engine.graph), 0, num_particles=300), _frames())
    np.testing.assert_array_equal(again, first)


def test_a_plates_per_replica_rule_travels_too():
    g = _plated(linear_gaussian.build_graph(linear_gaussian.Params()).with_factors(
        TravelPull("x", target=3.0, name="pull")))
    runs = []
    for graph in (g, None):
        engine = Engine(graph if graph is not None else _reloaded(runs[0][1]), 0,
                        num_particles=200)
        frames = _frames()
        engine.add(None, frames[0], rngs=[np.random.default_rng(5)], count=1)
        for f in frames[1:]:
            engine.step(f, lifecycle=False)
        runs.append((engine.beliefs["x"].x.copy(), engine.graph))
    assert runs[0][1].meta["rules"]["pull"] == f"{__name__}:pull_rule{PER_REPLICA}"
    np.testing.assert_array_equal(runs[1][0], runs[0][0])


def test_a_rule_that_cannot_be_found_is_an_error_naming_it():
    g = linear_gaussian.build_graph(linear_gaussian.Params())
    engine = Engine(g, 0, num_particles=50)
    d = json.loads(json.dumps(engine.graph.to_dict()))
    lik = _lik(g)
    d["meta"]["rules"][lik] = "no_such_module_of_rules:tempered"
    with pytest.raises(ValueError, match="no_such_module_of_rules:tempered") as err:
        Engine(FactorGraph.from_dict(d), 0)
    assert "\n" not in str(err.value) and "--import" in str(err.value) and lik in str(err.value)
    d["meta"]["rules"][lik] = f"{__name__}:not_defined_here"
    with pytest.raises(ValueError, match="not_defined_here"):
        Engine(FactorGraph.from_dict(d), 0)

    def local(ctx, factor, frame):
        return np.zeros(ctx.beliefs[factor.variables[0]].num)

    assert "<locals>" in rule_name(local)
    d["meta"]["rules"][lik] = rule_name(local)
    with pytest.raises(ValueError, match="inside a function"):
        Engine(FactorGraph.from_dict(d), 0)
    d["meta"]["rules"] = {"no-such-factor": f"{__name__}:tempered"}
    with pytest.raises(ValueError, match="no-such-factor"):
        Engine(FactorGraph.from_dict(d), 0)
    # a table given by the caller decides every rule (the saved names are replaced)
    d["meta"]["rules"] = {lik: "no_such_module_of_rules:tempered"}
    eng = Engine(FactorGraph.from_dict(d), 0, rules=DEFAULT_RULES, num_particles=50)
    assert eng.graph.meta["rules"][lik].startswith("pgm.inference.")


USER_FILE = '''
import numpy as np
from pgm.core.beliefs import Particles
from pgm.factors import LikelihoodFactor
from pgm.inference.rules import declare


class CliTravelStretch(LikelihoodFactor):
    def __init__(self, variable, *, scale, name=None):
        super().__init__(variable, name=name)
        self.scale = float(scale)

    def params(self):
        return {"scale": self.scale}

    def log_likelihood(self, x, ctx):
        return -0.5 * (x[:, 0] / self.scale) ** 2


@declare(CliTravelStretch, Particles)
def test_saving_a_rule_another_process_cannot_find_warns():
    """A rule of the running script (``__main__``) or one defined inside a function is
    saved by name, but a model naming it cannot be run elsewhere: saving it warns once per
    rule, naming it; a rule of an importable module says nothing."""
    import warnings

    g = linear_gaussian.build_graph(linear_gaussian.Params())
    engine = Engine(g, 0, num_particles=50)
    lik = _lik(g)
    for rule, why in (("__main__:my_rule", "running script"),
                      (f"{__name__}:test_x.<locals>.inner", "inside a function")):
        engine.graph.meta["rules"][lik] = rule
        with pytest.warns(UserWarning, match=why) as caught:
            engine.graph.to_dict()
        assert rule in str(caught[0].message) and lik in str(caught[0].message)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            engine.graph.to_dict()  # once
    engine.graph.meta["rules"][lik] = f"{__name__}:tempered"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        engine.graph.to_dict()


def stretch_rule(ctx, factor, frame):
    return factor.log_likelihood(ctx.beliefs[factor.variables[0]].x, frame)
'''


def test_the_command_line_imports_a_users_factors_and_rules(tmp_path, capsys):
    user = tmp_path / "travel_user_factors.py"
    user.write_text(USER_FILE)
    model = tmp_path / "model.json"
    # the model is saved by another process in practice: written here as its JSON
    g = linear_gaussian.build_graph(linear_gaussian.Params())
    d = g.to_dict()
    d["factors"].append({"type": "CliTravelStretch", "module": "travel_user_factors",
                         "name": "stretch", "kind": "likelihood", "variables": ["x"],
                         "params": {"scale": 2.0}})
    d.setdefault("meta", {})["rules"] = {"stretch": "travel_user_factors:stretch_rule"}
    model.write_text(json.dumps(d))
    code, _, err = run_cli(capsys, "graph", model, "--out", tmp_path / "g.dot")
    assert code == 2 and "CliTravelStretch" in err and "--import" in err
    assert err.strip().count("\n") == 0
    code, _, err = run_cli(capsys, "graph", model, "--out", tmp_path / "g.dot",
                           "--import", user)
    assert code == 0, err
    assert "stretch" in (tmp_path / "g.dot").read_text()
    from travel_user_factors import stretch_rule  # imported by --import, under its stem

    engine = Engine(FactorGraph.from_dict(d), 0, num_particles=50)
    assert engine._rule(engine.graph.factors["stretch"]) is stretch_rule
    code, _, err = run_cli(capsys, "graph", model, "--out", tmp_path / "g.dot",
                           "--import", tmp_path / "missing.py")
    assert code == 2 and "missing.py" in err


def test_an_experiment_imports_a_models_factors_for_every_run(tmp_path):
    from pgm.app.experiment_spec import _models
    from pgm.core.errors import InputError

    (tmp_path / "bench_user_factors.py").write_text(
        USER_FILE.replace("CliTravelStretch", "BenchTravelStretch"))
    d = linear_gaussian.build_graph(linear_gaussian.Params()).to_dict()
    d["factors"].append({"type": "BenchTravelStretch", "module": "bench_user_factors",
                         "name": "stretch", "kind": "likelihood", "variables": ["x"],
                         "params": {"scale": 2.0}})
    (tmp_path / "model.json").write_text(json.dumps(d))
    with pytest.raises(InputError, match="BenchTravelStretch"):
        _models([{"name": "model.json"}], tmp_path, "exp.toml")
    (spec,) = _models([{"name": "model.json", "import": "bench_user_factors.py"}], tmp_path,
                      "exp.toml")
    assert spec.options[0] == f"--import={(tmp_path / 'bench_user_factors.py').resolve()}"
    with pytest.raises(InputError, match="no such file"):
        _models([{"name": "model.json", "import": "gone.py"}], tmp_path, "exp.toml")


BENCH_USER = '''
import numpy as np
from pgm.core.beliefs import Particles
from pgm.factors import LikelihoodFactor
from pgm.inference.rules import declare


class BenchFlagFlat(LikelihoodFactor):
    def log_likelihood(self, x, ctx):
        return np.zeros(len(x))


@declare(BenchFlagFlat, Particles)
def flat_rule(ctx, factor, frame):
    return np.zeros(ctx.beliefs[factor.variables[0]].num)
'''


def test_pgm_bench_imports_a_users_code_for_every_run(tmp_path, capsys):
    from pgm.models import colour_pf
    from pgm.synthetic import demo_scene

    demo_scene(seed=0, n_frames=4).write_otb(tmp_path / "scene")
    (tmp_path / "bench_flag_user.py").write_text(BENCH_USER)
    x, y, w, h = 20, 100, 30, 80
    d = colour_pf.build_graph(colour_pf.Params(init_box=(x + w / 2, y + h / 2, w, h),
                                               num_particles=20)).to_dict()
    var = d["variables"][0]["name"]
    d["factors"].append({"type": "BenchFlagFlat", "module": "bench_flag_user", "name": "flat",
                         "kind": "likelihood", "variables": [var], "params": {}})
    (tmp_path / "model.json").write_text(json.dumps(d))
    (tmp_path / "exp.toml").write_text(
        'name = "flag"\nroot_seed = 1\nseeds = 1\nmax_frames = 3\nwrite_video = false\n'
        'sequences = ["scene"]\n[[models]]\nname = "model.json"\nlabel = "mine"\n')
    code, _, err = run_cli(capsys, "bench", tmp_path / "exp.toml", "--out", tmp_path / "out",
                           "--quiet")
    assert code == 2 and "BenchFlagFlat" in err  # the saved model names a factor not imported
    code, _, err = run_cli(capsys, "bench", tmp_path / "exp.toml", "--out", tmp_path / "out",
                           "--quiet", "--import", tmp_path / "bench_flag_user.py")
    assert code == 0, err
    rows = (tmp_path / "out" / "results.csv").read_text().strip().splitlines()
    assert len(rows) == 2  # a header and the one run
    (task,) = (tmp_path / "out" / "runs").rglob("task.json")
    options = json.loads(task.read_text())["run"]["options"]
    assert any(o.startswith("--import=") for o in options)
