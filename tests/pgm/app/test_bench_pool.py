"""Issue 26, item 10: ``pgm bench --jobs N`` runs every run on one pool of ``N`` workers,
started once with the toolkit imported (a fork server that imported it, where there is
one), not a process or an import per run."""

from __future__ import annotations

import multiprocessing
import sys

import pytest

from pgm.app import experiment as exp
from pgm.synthetic import demo_scene


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    d = tmp_path_factory.mktemp("pool")
    for k in range(2):
        demo_scene(seed=k, n_frames=4).write_otb(d / "seqs" / f"s{k}")
    path = d / "e.toml"
    path.write_text('seeds = 3\nmax_frames = 3\nsequences = ["seqs/*"]\n'
                    '[[models]]\nname = "colour-pf"\nparticles = 20\n')
    return exp.load_experiment(path)


def test_runs_share_the_pool_workers(experiment, tmp_path):
    runs = exp.expand(experiment)
    outcomes = list(exp._run_processes(runs, str(tmp_path), 2))
    assert sorted(r.index for r, _ in outcomes) == [r.index for r in runs]
    assert all(info["status"] == "complete" for _, info in outcomes)
    pids = {info["pid"] for _, info in outcomes}
    assert len(runs) == 6 and 1 <= len(pids) <= 2  # six runs, at most two processes


def test_no_more_workers_than_runs(experiment, tmp_path):
    runs = exp.expand(experiment)[:1]
    outcomes = list(exp._run_processes(runs, str(tmp_path), 8))
    assert [info["status"] for _, info in outcomes] == ["complete"]


def _imported_at_start() -> list[str]:
    """In a worker, before any run: which of the preloaded modules are imported."""
    return [m for m in exp.WORKER_PRELOAD if m in sys.modules]


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(),
                    reason="no fork server on this platform (spawn: each worker imports)")
def test_workers_start_with_the_toolkit_imported():
    """Every worker is a fork of a server that imported :data:`WORKER_PRELOAD` once, so
    a run does not pay the imports (the worker's initializer, which imports them where
    there is no fork server, is left out here to see the fork server's work)."""
    from concurrent.futures import ProcessPoolExecutor

    ctx = exp._worker_context()
    assert ctx.get_start_method() == "forkserver"
    with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
        loaded = pool.submit(_imported_at_start).result()
    assert loaded == list(exp.WORKER_PRELOAD)
