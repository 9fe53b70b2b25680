"""``pgm bench``: an experiment of many runs (sequences × models × seeds) from a TOML file.

::

    pgm bench EXPERIMENT.toml --out DIR [--jobs N] [--backend local|dask] [--address ADDR]

An experiment file names sequences (paths and globs relative to the file's folder, any
layout :func:`pgm.io.video.open_source` opens), models with their options (``pgm
track``'s options, spelt ``particles = 50`` or ``scale-noise = 0.01``) and seeds::

    name = "example"
    root_seed = 2024          # every run's generator derives from this one seed
    seeds = 3                 # a count (seeds 0, 1, 2) or a list: [0, 5, 7]
    max_frames = 8            # optional: stop every run after this many frames
    write_video = false       # optional (default false): annotated.mp4 per run
    sequences = ["../data/Crossing", "../data/OTB/*", {path = "clip.mp4", name = "clip"}]

    [[models]]
    name = "colour-pf"        # a model name (pgm.models.model_names()), or a saved model.json
    particles = 50

    [[models]]
    name = "part-graph"
    label = "part-graph-3"    # the folder and table name (default: the name)
    parts = 3

Each (sequence, model, seed) is one run, exactly ``pgm track SEQUENCE --model NAME
OPTIONS --seed S --out DIR/runs/<sequence>/<label>/<seed>`` (the command is written in
the run's ``task.json``), with the usual outputs written as the run goes. The per-run
seed ``S`` comes from :func:`run_seed_sequence`: ``numpy.random.SeedSequence(root_seed)``
spawned along the grid — by seed, then by the sequence's position, then by the model's
position — so a run's result depends on nothing but the experiment file: not on the
backend, the order of execution or ``--jobs``. Appending sequences, models or seeds
leaves the runs already there unchanged.

A run whose ``run.json`` says ``"complete": true`` and whose ``task.json`` matches the
experiment is skipped, so an interrupted experiment loses nothing: running it again runs
the rest. The results are ``DIR/results.csv`` (one row per run: ``sequence``, ``model``,
``seed``, every scalar metric of ``metrics.json`` and ``fps``), ``DIR/summary.csv``
(mean, sample standard deviation, min and max over seeds per sequence, model and metric)
and ``DIR/results.md`` (mean ± standard deviation over seeds).

Backends (:data:`BACKENDS`): ``local`` runs ``--jobs`` processes on this machine
(``--jobs 1``: in this process); ``dask`` ships each run as a task to a Dask
distributed cluster (``--address tcp://HOST:8786``; without it, a ``LocalCluster`` of
``--jobs`` worker processes). A task receives paths, never frames: the frames are read
where the task runs, so on a cluster the sequences and ``DIR`` must be at the same paths
on every worker (a shared file system). Every run uses one thread per numerical library
(the runs are the unit of parallelism), which also keeps the results bit-identical
between backends.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import os
import shlex
import signal
import socket
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError, Interrupted, one_line, user_message

from .experiment_results import (  # noqa: F401  (names of this module since the split)
    ExperimentResult,
    _cell,
    _columns,
    _count,
    _headline,
    _num,
    _read_json,
    _scalars,
    _stats,
    _summaries,
    _write_csv,
    _write_text,
    collect_rows,
    is_timing_column,
    run_state,
    write_results,
)
from .experiment_spec import (  # noqa: F401  (names of this module since the split)
    _SAFE_NAME,
    _SKIP_SUFFIXES,
    BACKENDS,
    CLUSTER_EXTRA,
    FAILURES_TXT,
    MAX_RUNS,
    PATH_OPTIONS,
    RESERVED_OPTIONS,
    RESULTS_CSV,
    RESULTS_MD,
    SUMMARY_CSV,
    TOP_LEVEL_KEYS,
    Experiment,
    ModelSpec,
    RunSpec,
    SequenceSpec,
    _candidates,
    _check_pairs,
    _check_single_object,
    _is_int,
    _log,
    _models,
    _option_tokens,
    _parse_track,
    _read_toml,
    _safe_name,
    _seeds,
    _sequences,
    _track_actions,
    load_experiment,
)

__all__ = ["BACKENDS", "Experiment", "ExperimentResult", "ModelSpec", "RunSpec",
           "SequenceSpec", "add_parser", "cmd_bench", "collect_rows", "expand",
           "is_timing_column", "load_experiment", "run_experiment", "run_seed_sequence",
           "run_state", "run_task", "write_results", "COMMANDS"]


# -- the grid -------------------------------------------------------------------------------
def run_seed_sequence(root_seed: int, seed: int, sequence_index: int,
                      model_index: int) -> np.random.SeedSequence:
    """The :class:`numpy.random.SeedSequence` of one run.

    ``SeedSequence(root_seed).spawn(seed + 1)[seed].spawn(sequence_index + 1)
    [sequence_index].spawn(model_index + 1)[model_index]``: the root spawned by seed,
    then by the sequence's position, then by the model's. Built directly from its spawn
    key ``(seed, sequence_index, model_index)``, which is what those spawns give.
    """
    return np.random.SeedSequence(root_seed, spawn_key=(seed, sequence_index, model_index))


def _seed_int(ss: np.random.SeedSequence) -> int:
    """A 64-bit integer from ``ss``: the ``--seed`` of the run's ``pgm track``."""
    words = ss.generate_state(2, np.uint32)
    return int(words[0]) | (int(words[1]) << 32)


def expand(experiment: Experiment) -> list[RunSpec]:
    """The experiment's runs, one per (sequence, model, seed), in table order.

    A run's seed depends only on ``root_seed``, its seed and the positions of its
    sequence and model in the file (:func:`run_seed_sequence`), never on which runs
    come before it, so any subset, order or backend gives the same results.
    """
    runs = []
    for q, seq in enumerate(experiment.sequences):
        for m, model in enumerate(experiment.models):
            for seed in experiment.seeds:
                key = (seed, q, m)
                ss = run_seed_sequence(experiment.root_seed, *key)
                runs.append(RunSpec(len(runs), seq.name, seq.path, model.label, model.name,
                                    model.options, seed, experiment.root_seed, key,
                                    _seed_int(ss), experiment.max_frames,
                                    experiment.write_video))
    return runs






# -- one run ---------------------------------------------------------------------------------
@contextlib.contextmanager
def _one_thread() -> Iterator[None]:
    """One thread per numerical library (BLAS/OpenMP, OpenCV, torch if loaded) for the
    duration, whatever the process: the same arithmetic on every backend."""
    import cv2
    from threadpoolctl import threadpool_limits

    cv_threads = cv2.getNumThreads()
    torch = sys.modules.get("torch")
    torch_threads = torch.get_num_threads() if torch is not None else None
    cv2.setNumThreads(1)
    if torch is not None:
        torch.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            yield
    finally:
        cv2.setNumThreads(cv_threads)
        if torch is not None and torch_threads is not None:
            torch.set_num_threads(torch_threads)


#: set by :func:`run_task` while a run is in progress in this process (read by the
#: SIGTERM handler of pool workers)
_IN_RUN = [False]


class _Collect(logging.Handler):
    """Keeps the messages of the ``pgm`` logger during a task."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(one_line(record.getMessage()))


def run_task(run: RunSpec, out: str) -> dict[str, Any]:
    """Run one task where it is called (this process, a pool worker or a Dask worker).

    Writes ``task.json`` (the run's settings and its ``pgm track`` command), then runs
    ``pgm track`` into ``run.folder(out)``; the frames are read here.

    Returns
    -------
    dict
        ``status`` (``"complete"`` or ``"failed"``), ``error`` (one line, or None),
        ``seconds`` (wall time), ``host``, ``pid`` and ``warnings`` (the run's warning
        lines).

    Raises
    ------
    KeyboardInterrupt
        SIGINT/SIGTERM during the run (its ``run.json`` then says
        ``"complete": false``).
    """
    from pgm.app.cli_track import cmd_track
    from pgm.io.outputs import write_json

    t0 = time.perf_counter()
    info: dict[str, Any] = {"status": "failed", "error": None, "seconds": 0.0,
                            "host": socket.gethostname(), "pid": os.getpid(), "warnings": []}
    folder = run.folder(out)
    handler = _Collect()
    log = logging.getLogger("pgm")
    log.addHandler(handler)
    try:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create {folder}: {exc.strerror or exc}") from None
        write_json(folder / "task.json",
                   {"format": "pgm-bench-task", "run": run.record(),
                    "command": shlex.join(["pgm", *run.argv(out)])})
        with warnings.catch_warnings(record=True) as caught, _one_thread(), \
                contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("always")
            _IN_RUN[0] = True
            try:
                cmd_track(_parse_track(run.argv(out)))
            finally:
                _IN_RUN[0] = False
        info["warnings"] = handler.messages + [one_line(w.message) for w in caught]
        info["status"] = "complete"
    except Exception as exc:  # noqa: BLE001 - a failed run is reported, the others go on
        msg = user_message(exc)
        info["error"] = msg if msg is not None else (f"internal error: "
                                                     f"{type(exc).__name__}: {one_line(exc)}")
    finally:
        log.removeHandler(handler)
        info["seconds"] = time.perf_counter() - t0
    return info


# -- backends --------------------------------------------------------------------------------
def _worker_init() -> None:
    """A pool worker: SIGTERM stops its run like ``pgm track`` (``run.json`` says why),
    or ends an idle worker at once; SIGINT is left to the parent, which stops the
    workers with SIGTERM."""
    def stop(signum, frame):  # noqa: ARG001 - signal handler signature
        if _IN_RUN[0]:
            raise Interrupted(signum)
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    import importlib

    for name in WORKER_PRELOAD:  # done already in a fork of the fork server
        importlib.import_module(name)


Outcome = tuple[RunSpec, dict[str, Any]]


def _run_inline(runs: Sequence[RunSpec], out: str) -> Iterator[Outcome]:
    """The local backend with one job: the runs one after the other, in this process."""
    for run in runs:
        yield run, run_task(run, out)


#: what every run imports, imported once by the fork server that starts the local
#: backend's workers (each worker is a fork of it, its imports done), or by each worker
#: as it starts where there is no fork server (spawn)
WORKER_PRELOAD = ("pgm.app.experiment", "pgm.app.cli", "pgm.app.runner", "pgm.models",
                  "pgm.app.view", "pgm.app.report", "pgm.io.video", "PIL.Image",
                  "pgm.evaluation.single_object", "pgm.evaluation.mot", "threadpoolctl")


def _worker_context():
    """The local backend's start method: a fork server that has imported
    :data:`WORKER_PRELOAD` (once for every worker of every pool), else spawn."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(WORKER_PRELOAD))
    return ctx


def _outcomes(futures: dict, completed, failure: str) -> Iterator[Outcome]:
    """``(run, outcome)`` of each future in the order ``completed`` yields them (a pool's
    or a cluster's ``as_completed``); a future that raises (a dead worker, a lost task)
    fails its run only, with ``failure`` and the error as its message."""
    for fut in completed:
        run = futures[fut]
        try:
            yield run, fut.result()
        except Exception as exc:  # noqa: BLE001 - a dead worker fails its run only
            yield run, {"status": "failed", "seconds": 0.0, "warnings": [],
                        "error": f"{failure}: {type(exc).__name__}: {one_line(exc)}"}


def _run_processes(runs: Sequence[RunSpec], out: str, jobs: int) -> Iterator[Outcome]:
    """The local backend: one pool of ``jobs`` worker processes for all the runs, each
    worker started once with the toolkit imported (:func:`_worker_context`); outcomes
    as they finish; interrupted or closed early, it stops the runs in progress."""
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(max_workers=min(jobs, len(runs)) or 1,
                               mp_context=_worker_context(), initializer=_worker_init)
    futures = {pool.submit(run_task, run, out): run for run in runs}
    try:
        yield from _outcomes(futures, as_completed(futures), "worker process failed")
    except BaseException:
        for fut in futures:
            fut.cancel()
        procs = list(getattr(pool, "_processes", None) or {})
        for pid in procs:  # stop the runs in progress: each records "interrupted"
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _dask():
    """``distributed``, or an :class:`InputError` naming the extra to install."""
    try:
        import distributed
    except ImportError:
        raise InputError(f"the dask backend needs Dask distributed: {CLUSTER_EXTRA}") from None
    return distributed


def _run_dask(runs: Sequence[RunSpec], out: str, jobs: int,
              address: str | None) -> Iterator[Outcome]:
    """The Dask backend: one task per run on the cluster at ``address`` (else on a
    ``LocalCluster`` of ``jobs`` single-threaded worker processes), outcomes as they
    finish."""
    distributed = _dask()
    cluster = None
    try:
        if address is None:
            cluster = distributed.LocalCluster(n_workers=jobs, threads_per_worker=1,
                                               processes=True, dashboard_address=None)
            client = distributed.Client(cluster)
        else:
            client = distributed.Client(address, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        where = address or "a LocalCluster"
        raise InputError(f"cannot start the Dask client for {where}: {one_line(exc)}") \
            from None
    try:
        futures = {client.submit(run_task, run, out, pure=False): run for run in runs}
        try:
            yield from _outcomes(futures, distributed.as_completed(list(futures)),
                                 "Dask task failed")
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_experiment(experiment: Experiment, out: str | Path, *, jobs: int = 1,
                   backend: str = "local", address: str | None = None,
                   progress: Callable[[str], None] | None = None) -> ExperimentResult:
    """Run every run of ``experiment`` not yet complete in ``out``, then write the tables.

    Parameters
    ----------
    experiment : Experiment
    out : str or Path
        The experiment's folder (``runs/``, ``results.csv``, ``summary.csv``,
        ``results.md``, a copy of the file as ``experiment.toml``).
    jobs : int
        Worker processes on this machine: the local backend's pool (``1``: in this
        process) or the Dask ``LocalCluster``'s workers (without ``address``).
    backend : {"local", "dask"}
    address : str, optional
        Dask scheduler address (``tcp://host:8786``); ``backend="dask"`` only.
    progress : callable, optional
        Called with one line per finished run (and a first line saying what runs).

    Returns
    -------
    ExperimentResult

    Raises
    ------
    InputError
        A bad backend, address or ``out``; Dask not installed; or runs that failed
        (after every other run has finished and the tables are written; the errors are
        in ``out/failures.txt``).
    KeyboardInterrupt
        On SIGINT/SIGTERM: the runs in progress record ``"complete": false``, the tables
        of the complete runs are written, and running the experiment again finishes it.
    """
    say = progress or (lambda line: None)
    if backend == "ray":
        raise InputError(f"the cluster backend is Dask distributed, not Ray: use --backend "
                         f"dask ({CLUSTER_EXTRA})")
    if backend not in BACKENDS:
        raise InputError(f"--backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if address is not None and backend != "dask":
        raise InputError("--address applies to --backend dask")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"--jobs must be a positive integer, got {jobs!r}")
    if backend == "dask":
        _dask()
    t0 = time.perf_counter()
    out_dir = Path(out).expanduser()
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"--out {out_dir} exists and is not a folder")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create --out {out_dir}: {exc.strerror or exc}") from None
    out_dir = out_dir.resolve()
    with contextlib.suppress(OSError):
        (out_dir / "experiment.toml").write_bytes(experiment.path.read_bytes())
    runs = expand(experiment)
    result = ExperimentResult(runs)
    states = {run.index: run_state(run, out_dir) for run in runs}
    result.skipped = [r for r in runs if states[r.index] == "complete"]
    pending = [r for r in runs if states[r.index] != "complete"]
    changed = sum(states[r.index] == "changed" for r in pending)
    workers = 1 if backend == "local" and jobs == 1 else min(jobs, max(len(pending), 1))
    where = ("in this process" if backend == "local" and workers == 1 else
             f"on {workers} local processes" if backend == "local" else
             f"on the Dask cluster at {address}" if address else
             f"on a Dask LocalCluster of {workers} workers")
    say(f"pgm bench: {experiment.name}: {_count(len(runs), 'run')} "
        f"({_count(len(experiment.sequences), 'sequence')} × "
        f"{_count(len(experiment.models), 'model')} × "
        f"{_count(len(experiment.seeds), 'seed')}); "
        f"{len(result.skipped)} complete, skipped; running {len(pending)} {where}"
        + (f" ({changed} finished with other settings, run again)" if changed else ""))
    bar = None
    if pending and progress is not None and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(pending), unit="run", desc="pgm bench", leave=False,
                   file=sys.stderr)

        def say(line: str) -> None:
            with tqdm.external_write_mode(file=sys.stderr):
                progress(line)

    failures: list[str] = []
    outcomes: Iterator[Outcome] = iter(())
    try:
        if not pending:
            pass
        elif backend == "dask":
            outcomes = _run_dask(pending, str(out_dir), workers, address)
        elif workers == 1:
            outcomes = _run_inline(pending, str(out_dir))
        else:
            outcomes = _run_processes(pending, str(out_dir), workers)
        width = len(str(len(pending)))
        for k, (run, info) in enumerate(outcomes, 1):
            result.ran.append(run)
            head = f"[{k:>{width}}/{len(pending)}] {run.label}"
            if info.get("status") == "complete":
                say(f"{head}: complete in {info.get('seconds', 0.0):.1f} s"
                    + _headline(run.folder(out_dir)))
            else:
                error = info.get("error") or "failed"
                result.failed.append((run, error))
                failures.append(f"{run.label}: {error}")
                say(f"{head}: failed: {error}")
            for line in dict.fromkeys(info.get("warnings") or ()):
                _log.warning("%s: %s", run.label, line)
            if bar is not None:
                bar.update(1)
    finally:
        close = getattr(outcomes, "close", None)
        if close is not None:
            close()  # a backend interrupted mid-way stops its workers
        if bar is not None:
            bar.close()
        write_results(experiment, runs, out_dir)
        result.rows = collect_rows(runs, out_dir)
        result.seconds = time.perf_counter() - t0
        fail_file = out_dir / FAILURES_TXT
        if failures:
            fail_file.write_text("\n".join(failures) + "\n", encoding="utf-8")
        else:
            fail_file.unlink(missing_ok=True)
    if result.failed:
        run, error = result.failed[0]
        raise InputError(f"{len(result.failed)} of {len(runs)} runs failed (first: "
                         f"{run.label}: {error}); the other runs are in "
                         f"{out_dir / RESULTS_CSV}, the errors in {out_dir / FAILURES_TXT}")
    return result


# -- the command -----------------------------------------------------------------------------
def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pgm bench`` to the ``pgm`` sub-commands."""
    from pgm.app.cli import _path, _positive_int

    b = subparsers.add_parser(
        "bench", help="run an experiment: sequences × models × seeds from a TOML file",
        description="Run every (sequence, model, seed) of an experiment file as one 'pgm "
                    "track' run into DIR/runs/<sequence>/<model>/<seed>/, skipping runs "
                    "already complete, and write DIR/results.csv (one row per run), "
                    "DIR/summary.csv and DIR/results.md (mean ± standard deviation over "
                    "seeds). See docs/experiments/example.toml for the file's format.",
        epilog="examples:\n  pgm bench docs/experiments/example.toml --out bench_out "
               "--jobs 2\n  pgm bench exp.toml --out /shared/exp --backend dask "
               "--address tcp://10.0.0.5:8786")
    b.add_argument("experiment", type=_path("EXPERIMENT.toml"), metavar="EXPERIMENT.toml",
                   help="the experiment file")
    b.add_argument("--out", type=_path("--out"), required=True, metavar="DIR",
                   help="the experiment's folder")
    b.add_argument("--jobs", type=_positive_int("--jobs"), default=1, metavar="N",
                   help="worker processes on this machine: the local pool (1: in this "
                        "process) or the Dask LocalCluster (default: %(default)s)")
    b.add_argument("--backend", default="local", metavar="local|dask",
                   help="local processes or Dask distributed "
                        f"({CLUSTER_EXTRA}) (default: %(default)s)")
    b.add_argument("--address", default=None, metavar="ADDR",
                   help="dask: the scheduler, e.g. tcp://10.0.0.5:8786 (default: start a "
                        "LocalCluster of --jobs workers)")
    b.add_argument("--quiet", action="store_true", help="no line per finished run")
    b.add_argument("--import", dest="imports", action="append", default=[],
                   metavar="MODULE_OR_FILE",
                   help="import a module or .py file of your own factors, rules or models "
                        "first, here and in every run (as a model entry's import = ...); "
                        "repeatable (default: none)")
    return b


def cmd_bench(args: argparse.Namespace) -> int:
    """``pgm bench``: load, run, write the tables, print where they are."""
    experiment = load_experiment(args.experiment)
    if args.imports:  # every run imports them too (pgm.app.cli imported them here)
        import dataclasses

        tokens = tuple(f"--import={Path(i).resolve() if i.endswith('.py') else i}"
                       for i in args.imports)
        experiment = dataclasses.replace(experiment, models=tuple(
            dataclasses.replace(m, options=tokens + tuple(m.options))
            for m in experiment.models))
    progress = None if args.quiet else (lambda line: print(line, file=sys.stderr,
                                                           flush=True))
    result = run_experiment(experiment, args.out, jobs=args.jobs, backend=args.backend,
                            address=args.address, progress=progress)
    out = Path(args.out)
    print(f"pgm bench: {len(result.rows)} of {len(result.runs)} runs complete "
          f"({len(result.ran)} run now, {len(result.skipped)} skipped) in "
          f"{result.seconds:.1f} s; wrote {out / RESULTS_CSV}, {out / SUMMARY_CSV} and "
          f"{out / RESULTS_MD}")
    return 0


#: ``pgm`` sub-commands of this module
COMMANDS = {"bench": cmd_bench}
