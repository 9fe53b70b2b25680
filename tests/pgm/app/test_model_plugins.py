"""A model in a package of its own is found through the ``pgm.models`` entry points: it is
listed, its options are parsed, it draws and tracks; a broken one is a one-line error."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PLUGIN = '''
import sys

from pgm.models import colour_pf
from pgm.models.config import ModelConfig, Option, int_in


def build(config, values, video):
    n = values.get("particles_per_box") or 30
    return colour_pf.build_graph(colour_pf.Params(init_box=video.init_box or (50, 50, 20, 30),
                                                  num_particles=n))


CONFIG = ModelConfig("my-pf", "single-object", sys.modules[__name__], "a plug-in",
                     options=(Option("--particles-per-box", None,
                                     type=int_in("--particles-per-box", 1, 500),
                                     help="particles (default: 30)"),),
                     build=build)
'''


@pytest.fixture()
def site(tmp_path):
    """A package and the metadata ``pip install`` writes for its entry points."""
    root = tmp_path / "site"
    (root / "my_models").mkdir(parents=True)
    (root / "my_models" / "__init__.py").write_text("")
    (root / "my_models" / "pf.py").write_text(textwrap.dedent(PLUGIN))
    dist = root / "my_models-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: my-models\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[pgm.models]\nmy-pf = my_models.pf:CONFIG\n"
                                           "broken = my_models.missing:CONFIG\n")
    return root


def _pgm(site, *argv, cwd=None):
    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run([sys.executable, "-m", "pgm.app.cli", *map(str, argv)], env=env,
                          capture_output=True, text=True, cwd=cwd, timeout=120)


def test_a_plugin_model_is_listed_parsed_drawn_and_tracked(site, tmp_path):
    res = _pgm(site, "track", "--model", "my-pf", "--help")
    assert res.returncode == 0, res.stderr
    assert "--particles-per-box" in res.stdout and "my-pf" in res.stdout
    res = _pgm(site, "graph", "my-pf", "--particles-per-box", "12", "--out", tmp_path / "g.dot")
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "g.dot").read_text().startswith("graph")
    from pgm.synthetic import demo_scene

    demo_scene(seed=0, n_frames=5).write_otb(tmp_path / "scene")
    res = _pgm(site, "track", tmp_path / "scene", "--model", "my-pf", "--particles-per-box",
               "20", "--out", tmp_path / "run", "--no-video", "--quiet")
    assert res.returncode == 0, res.stderr
    assert len((tmp_path / "run" / "tracks.txt").read_text().splitlines()) == 5
    # its option is its own: another model refuses it, naming the model that takes it
    res = _pgm(site, "track", tmp_path / "scene", "--model", "colour-pf",
               "--particles-per-box", "20", "--out", tmp_path / "run2")
    assert res.returncode == 2 and "my-pf" in res.stderr and "Traceback" not in res.stderr


def test_a_broken_plugin_is_a_one_line_error_and_breaks_no_other_model(site, tmp_path):
    res = _pgm(site, "graph", "broken", "--out", tmp_path / "g.dot")
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "broken" in res.stderr and "cannot be loaded" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    res = _pgm(site, "graph", "colour-pf", "--out", tmp_path / "c.dot")
    assert res.returncode == 0, res.stderr


def test_the_toolkit_declares_its_models_as_entry_points():
    """The package metadata and the built-in table agree (a fresh install finds them)."""
    from importlib.metadata import entry_points

    from pgm.models import BUILTIN

    eps = {ep.name: ep.value for ep in entry_points(group="pgm.models")}
    if not eps:
        pytest.skip("pgm is not installed as a distribution here (no entry points)")
    assert {k: v for k, v in eps.items() if k in BUILTIN} == BUILTIN
    text = (Path(__file__).resolve().parents[3] / "pyproject.toml").read_text()
    for name, target in BUILTIN.items():
        assert f'{name} = "{target}"' in text


def test_a_saved_model_loads_in_a_fresh_process(tmp_path):
    """Model modules are imported lazily; loading a saved graph still finds its factor
    types and its readout (a fresh ``pgm report``, ``pgm view`` or ``pgm track --model
    model.json`` reads model.json files)."""
    from pgm.models import get_config

    for name in ("single-object", "vb-phd", "multi-pf"):
        graph, _ = get_config(name).example_graph()
        graph.save(tmp_path / f"{name}.json")
    code = ("import sys; from pgm.core.graph import FactorGraph; "
            "from pgm.core.readout import get_readout; "
            "gs = [FactorGraph.load(p) for p in sys.argv[1:]]; "
            "[get_readout(g.meta['readout']) for g in gs if 'readout' in g.meta]; print('ok')")
    res = subprocess.run([sys.executable, "-c", code, *sorted(map(str, tmp_path.glob("*.json")))],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr
