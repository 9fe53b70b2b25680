"""
Tutorial 8 — your model in ``pgm track``, ``pgm graph`` and ``pgm bench``
=========================================================================

A model of your own, in a package of your own, appears in the command line without a
line of the toolkit edited: the package declares a :class:`pgm.models.config.ModelConfig`
as an entry point of the group ``pgm.models``, and the toolkit finds it there, as it finds
its own models. The config says what the model tracks, which command-line options it
takes and how it builds its graph for a video. Run it as a script::

    python docs/tutorials/08_model_plugin.py --out tutorial_out

The package's ``pyproject.toml`` holds the line that registers it::

    [project.entry-points."pgm.models"]
    brightness-pf = "my_pgm_models.brightness:CONFIG"

``pip install -e .`` in the package's folder writes that entry point into the
environment's metadata. So that this tutorial installs nothing into your environment,
it writes the same metadata (a ``.dist-info`` folder) next to the package and runs the
``pgm`` commands with that folder on ``PYTHONPATH``.
"""

# %%
import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

from pgm.synthetic import demo_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(),
                                                              "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out).resolve()
out.mkdir(parents=True, exist_ok=True)

# %%
# The model: the toolkit's colour particle filter with its colour histogram swapped for a
# brightness cue of our own, and one option of our own, ``--tau``. ``build`` receives the
# option values and what the toolkit knows of the video (its size, frame rate, the first
# box); it returns a :class:`pgm.FactorGraph`.
package = out / "site" / "my_pgm_models"
package.mkdir(parents=True, exist_ok=True)
(package / "__init__.py").write_text("")
(package / "brightness.py").write_text(textwrap.dedent('''
    """A colour PF whose likelihood is the box's mean brightness (a model of our own)."""
    import sys

    import numpy as np

    import pgm
    from pgm.models import colour_pf
    from pgm.models.config import ModelConfig, Option, finite_float


    class MeanBrightness(pgm.LikelihoodFactor):
        """-|mean grey level in the box - its first-frame value| / tau."""

        def __init__(self, variable, *, tau=4.0, name=None):
            super().__init__(variable, name=name)
            self.tau, self.template = float(tau), None

        def params(self):
            return {"tau": self.tau}

        def _means(self, x, ctx):
            grey = ctx.image.mean(axis=2) if ctx.image.ndim == 3 else ctx.image
            ii = np.pad(grey.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
            h, w = grey.shape
            x0 = np.clip(x[:, 0] - x[:, 2] / 2, 0, w - 1).astype(int)
            x1 = np.clip(x[:, 0] + x[:, 2] / 2, x0 + 1, w).astype(int)
            y0 = np.clip(x[:, 1] - x[:, 3] / 2, 0, h - 1).astype(int)
            y1 = np.clip(x[:, 1] + x[:, 3] / 2, y0 + 1, h).astype(int)
            s = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
            return s / ((x1 - x0) * (y1 - y0))

        def initialize(self, ctx, mean):
            self.template = float(self._means(np.asarray(mean)[None], ctx)[0])

        def log_likelihood(self, x, ctx):
            return -np.abs(self._means(x, ctx) - self.template) / self.tau


    def build(config, values, video):
        params = colour_pf.Params(init_box=video.init_box or (320, 240, 40, 80),
                                  num_particles=video.particles or 100)
        graph = colour_pf.build_graph(params)
        factors = [f for f in graph.factors.values() if f.kind != "likelihood"]
        tau = values.get("tau") or 4.0
        return pgm.FactorGraph(list(graph.variables.values()),
                               factors + [MeanBrightness("object", tau=tau)],
                               name="brightness-pf", meta=graph.meta)


    CONFIG = ModelConfig(
        "brightness-pf", "single-object", sys.modules[__name__],
        "a colour PF whose likelihood is the box's mean brightness",
        options=(Option("--tau", None, type=finite_float("--tau"),
                        help="brightness tolerance (grey levels; default: 4)"),),
        build=build)
'''))

# %%
# The metadata ``pip install`` would write: a distribution with one entry point.
dist = out / "site" / "my_pgm_models-0.1.dist-info"
dist.mkdir(exist_ok=True)
(dist / "METADATA").write_text("Metadata-Version: 2.1\nName: my-pgm-models\nVersion: 0.1\n")
(dist / "entry_points.txt").write_text(
    "[pgm.models]\nbrightness-pf = my_pgm_models.brightness:CONFIG\n")
env = {**os.environ, "PYTHONPATH": os.pathsep.join(
    [str(out / "site")] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])}


def pgm_cli(*argv: str) -> str:
    """Run ``pgm ARGV`` as a user would (a new process); its output."""
    res = subprocess.run([sys.executable, "-m", "pgm.app.cli", *map(str, argv)],
                         capture_output=True, text=True, env=env)
    if res.returncode != 0:
        raise SystemExit(f"pgm {' '.join(map(str, argv))} failed:\n{res.stderr}")
    return res.stdout


# %%
# The toolkit now lists the model, shows its option in ``--help``, draws it and tracks with
# it — the same commands as for its own models.
help_text = pgm_cli("track", "--model", "brightness-pf", "--help")
print("\n".join(line for line in help_text.splitlines() if "--tau" in line or "brightness"
                in line))
print(pgm_cli("graph", "brightness-pf", "--out", out / "brightness_graph.png").strip())
scene = out / "scene"
demo_scene(seed=0, n_frames=args.max_frames or 60).write_otb(scene)
print(pgm_cli("track", scene, "--model", "brightness-pf", "--tau", "6", "--out",
              out / "run", "--no-video"))  # (--quiet would print nothing but errors)
