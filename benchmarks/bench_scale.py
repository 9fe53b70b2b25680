"""``pgm bench`` at scale: wall time of one experiment on 1 and 2 local workers, and what
the Dask backend costs per run.

Runs the experiment (default: ``docs/experiments/example.toml``, 27 runs on
``../shared/data``; a synthetic one of the same shape where that is absent, or with
``--synthetic``) into a fresh folder each time:

* local, ``--jobs 1`` (in this process) and ``--jobs 2`` (a process pool, its start
  included);
* Dask, a ``LocalCluster`` of 2 workers started by the run (its start included) and the
  same on a cluster already running (``--address``): the latter minus local ``--jobs 2``,
  divided by the number of runs, is the Dask backend's overhead per run;
* the round trip of a trivial task (``int(1)``) through each, median of 50.

    python benchmarks/bench_scale.py [--experiment FILE.toml | --synthetic]
        [--max-frames K] [--repeats R]

The example's runs are 8 frames long, so process and cluster start-up dominate its wall
time; ``--max-frames 60`` makes each run long enough for the workers to pay off.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, machine_note, print_table, single_thread  # noqa: E402

single_thread()


from pgm.app import experiment as exp  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "experiments" / "example.toml"
SYNTHETIC = """
name = "synthetic"
root_seed = 2024
seeds = 3
max_frames = 8
sequences = ["seqs/*"]

[[models]]
name = "colour-pf"
particles = 30

[[models]]
name = "part-graph"
label = "part-graph-2"
parts = 2
particles = 30

[[models]]
name = "single-object"
particles = 30
scale-noise = 0.005
"""


def synthetic_experiment(folder: Path) -> Path:
    """Three 8-frame synthetic OTB sequences (320x240) and the example's models."""
    from pgm.synthetic import demo_scene

    for k in range(3):
        demo_scene(seed=k, n_frames=8).write_otb(folder / "seqs" / f"synthetic{k}")
    path = folder / "synthetic.toml"
    path.write_text(SYNTHETIC)
    return path


def timed_run(experiment, **kwargs) -> float:
    """Wall seconds of one whole experiment into a fresh folder."""
    with tempfile.TemporaryDirectory(prefix="bench_scale_") as out:
        t0 = time.perf_counter()
        result = exp.run_experiment(experiment, out, **kwargs)
        secs = time.perf_counter() - t0
    if result.failed or len(result.ran) != experiment.n_runs:
        raise SystemExit(f"experiment did not run whole: {result.failed[:1]}")
    return secs


def round_trip_ms(submit, n: int = 50) -> float:
    """Median milliseconds of ``submit(int, 1)`` → result."""
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        submit(int, 1).result()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--experiment", type=Path, default=None,
                    help="experiment file (default: docs/experiments/example.toml)")
    ap.add_argument("--synthetic", action="store_true",
                    help="a synthetic experiment of the example's shape (no shared data)")
    ap.add_argument("--max-frames", type=int, default=None, metavar="K",
                    help="frames per run (default: the experiment's max_frames)")
    ap.add_argument("--repeats", type=int, default=1, help="runs per setting (median)")
    args = ap.parse_args()
    if args.repeats < 1 or (args.max_frames is not None and args.max_frames < 1):
        raise SystemExit("--repeats and --max-frames must be >= 1")
    with tempfile.TemporaryDirectory(prefix="bench_scale_data_") as tmp:
        if args.synthetic or (args.experiment is None and not SHARED_DATA.is_dir()):
            path = synthetic_experiment(Path(tmp))
        else:
            path = args.experiment or EXAMPLE
        experiment = exp.load_experiment(path)
        if args.max_frames is not None:
            experiment = dataclasses.replace(experiment, max_frames=args.max_frames)
        n = experiment.n_runs
        print(machine_note())
        print(f"experiment: {path.name}, {n} runs ({len(experiment.sequences)} sequences x "
              f"{len(experiment.models)} models x {len(experiment.seeds)} seeds, "
              f"max_frames={experiment.max_frames}); {args.repeats} repeat(s), median")

        def median(**kwargs) -> float:
            return statistics.median(timed_run(experiment, **kwargs)
                                     for _ in range(args.repeats))

        rows = []
        t1 = median(jobs=1)
        rows.append(["local", 1, "in this process", t1, 1e3 * t1 / n, 1.0])
        t2 = median(jobs=2)
        rows.append(["local", 2, "process pool, start included", t2, 1e3 * t2 / n, t1 / t2])
        dask_rows = []
        try:
            import distributed
        except ImportError:
            distributed = None
        if distributed is not None:
            td = median(backend="dask", jobs=2)
            rows.append(["dask", 2, "LocalCluster, start included", td, 1e3 * td / n, t1 / td])
            t0 = time.perf_counter()
            with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                          dashboard_address=None) as cluster, \
                    distributed.Client(cluster) as client:
                start = time.perf_counter() - t0
                client.submit(int, 0, pure=False).result()  # workers up
                tr = median(backend="dask", address=cluster.scheduler_address)
                rt_dask = round_trip_ms(lambda f, a: client.submit(f, a, pure=False))
            rows.append(["dask", 2, "cluster already running", tr, 1e3 * tr / n, t1 / tr])
            dask_rows = [start, rt_dask, 1e3 * (tr - t2) / n, 1e3 * (td - t2) / n]
        from concurrent.futures import ProcessPoolExecutor
        from multiprocessing import get_context

        with ProcessPoolExecutor(2, mp_context=get_context("forkserver")) as pool:
            pool.submit(int, 0).result()
            rt_pool = round_trip_ms(pool.submit)
        print_table(["backend", "workers", "how", "wall s", "ms per run", "speed-up vs 1"],
                    rows, title="wall time of the whole experiment")
        if dask_rows:
            print_table(["LocalCluster start s", "trivial task round trip ms (dask)",
                         "trivial task round trip ms (process pool)",
                         "dask overhead ms per run (running cluster - local 2)",
                         "same, cluster start included"],
                        [[dask_rows[0], dask_rows[1], rt_pool, dask_rows[2], dask_rows[3]]],
                        title="Dask backend overhead")
        else:
            print(f"\nDask distributed not installed ({exp.CLUSTER_EXTRA}); trivial task "
                  f"round trip through the process pool: {rt_pool:.3g} ms")


if __name__ == "__main__":
    main()
