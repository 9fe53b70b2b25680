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
import csv
import functools
import glob
import io
import json
import logging
import math
import os
import re
import shlex
import signal
import socket
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError, Interrupted, one_line, user_message

__all__ = ["BACKENDS", "Experiment", "ExperimentResult", "ModelSpec", "RunSpec",
           "SequenceSpec", "add_parser", "cmd_bench", "collect_rows", "expand",
           "is_timing_column", "load_experiment", "run_experiment", "run_seed_sequence",
           "run_state", "run_task", "write_results", "COMMANDS"]

#: the values of ``--backend``
BACKENDS = ("local", "dask")
#: what ``pip`` installs for the ``dask`` backend
CLUSTER_EXTRA = "pip install pgm-tracking[cluster]"
#: keys of an experiment file's top level
TOP_LEVEL_KEYS = ("name", "root_seed", "seeds", "max_frames", "write_video", "sequences",
                  "models")
#: ``pgm track`` options that a model entry may not set, and what sets them instead
RESERVED_OPTIONS = {
    "help": "nothing", "source": "the sequences list", "out": "pgm bench --out",
    "seed": "root_seed and seeds", "quiet": "pgm bench", "model": "the entry's name",
    "no_video": "write_video (top level)", "max_frames": "max_frames (top level)",
    "init": "the sequence's ground truth (its first box)",
    "gt": "the sequence's own ground truth",
    "detections": "the sequence's det/det.txt (detector = \"public\")",
}
#: options holding a file path, resolved relative to the experiment file's folder
PATH_OPTIONS = ("gpdm", "dbn")
#: files of the results
RESULTS_CSV, SUMMARY_CSV, RESULTS_MD, FAILURES_TXT = ("results.csv", "summary.csv",
                                                      "results.md", "failures.txt")
_SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+=-]*")
_SKIP_SUFFIXES = frozenset({".txt", ".ini", ".md", ".json", ".csv", ".xml", ".yaml", ".yml",
                            ".toml", ".npz", ".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"})
_log = logging.getLogger("pgm")


# -- the experiment file -------------------------------------------------------------------
@dataclass(frozen=True)
class SequenceSpec:
    """One sequence of an experiment.

    Attributes
    ----------
    name : str
        The folder name of its runs and its name in the tables.
    path : str
        Absolute path of the video or sequence folder.
    has_gt, has_det : bool
        Whether the layout has a ground-truth file / MOTChallenge public detections.
    """

    name: str
    path: str
    has_gt: bool
    has_det: bool


@dataclass(frozen=True)
class ModelSpec:
    """One model entry of an experiment.

    Attributes
    ----------
    label : str
        The folder name of its runs and its name in the tables.
    name : str
        A model name (:func:`pgm.models.model_names`), or the absolute path of a saved
        ``model.json``.
    options : tuple of str
        ``pgm track`` arguments (``--particles=50``, ``--show-particles``).
    multi_target : bool
        Whether it is run by :func:`pgm.app.runner.track_multi`.
    detector : str or None
        Its ``detector`` option (multi-target models).
    """

    label: str
    name: str
    options: tuple[str, ...]
    multi_target: bool
    detector: str | None = None


@dataclass(frozen=True)
class Experiment:
    """An experiment file, checked.

    Attributes
    ----------
    path : Path
        The TOML file.
    name : str
    root_seed : int
    seeds : tuple of int
    max_frames : int or None
    write_video : bool
    sequences : tuple of SequenceSpec
    models : tuple of ModelSpec
    """

    path: Path
    name: str
    root_seed: int
    seeds: tuple[int, ...]
    max_frames: int | None
    write_video: bool
    sequences: tuple[SequenceSpec, ...]
    models: tuple[ModelSpec, ...]

    @property
    def n_runs(self) -> int:
        """Size of the grid: sequences × models × seeds."""
        return len(self.sequences) * len(self.models) * len(self.seeds)


def _read_toml(path: Path) -> dict[str, Any]:
    """The parsed file; every failure an :class:`InputError` naming it."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        try:
            import tomli as tomllib
        except ModuleNotFoundError:
            raise InputError("reading an experiment file needs Python >= 3.11 (tomllib) or "
                             "the tomli package: pip install tomli") from None
    if path.is_dir():
        raise InputError(f"experiment file {path} is a folder")
    if not path.is_file():
        raise InputError(f"no such experiment file: {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"experiment file {path} is not UTF-8 text") from None
    except OSError as exc:
        raise InputError(f"cannot read experiment file {path}: {exc.strerror or exc}") \
            from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"experiment file {path} is not valid TOML: {one_line(exc)}") \
            from None


def _is_int(value: Any) -> bool:
    """Whether ``value`` is an integer (TOML's ``true`` is not)."""
    return isinstance(value, int) and not isinstance(value, bool)


#: most runs an experiment may hold (sequences × models × seeds), checked before any
#: is listed: a typo such as ``seeds = 1000000000`` is refused at once, not after
#: filling the memory
MAX_RUNS = 100_000


def _seeds(value: Any, where: str) -> tuple[int, ...]:
    """``seeds``: a count ``1 <= n <=`` :data:`MAX_RUNS` (seeds ``0..n-1``) or a list of
    distinct integers ``>= 0``."""
    if _is_int(value):
        if value < 1:
            raise InputError(f"{where}: seeds must be a count >= 1 or a list of seeds, "
                             f"got {value}")
        if value > MAX_RUNS:
            raise InputError(f"{where}: seeds = {value} is more than an experiment may "
                             f"run ({MAX_RUNS} runs at most)")
        return tuple(range(value))
    if isinstance(value, list):
        if not value:
            raise InputError(f"{where}: seeds is an empty list")
        bad = [v for v in value if not _is_int(v) or v < 0]
        if bad:
            raise InputError(f"{where}: seeds must be integers >= 0, got {bad[0]!r}")
        if len(set(value)) != len(value):
            dup = next(v for v in value if value.count(v) > 1)
            raise InputError(f"{where}: seed {dup} is listed twice")
        return tuple(value)
    raise InputError(f"{where}: seeds must be a count >= 1 or a list of integers, got "
                     f"{value!r}")


def _safe_name(text: str) -> str:
    """``text`` with every character a folder name should not hold made ``_``."""
    name = re.sub(r"[^A-Za-z0-9._+=-]", "_", text).lstrip("._-")
    return name or "sequence"


def _candidates(pattern: str, base: Path, where: str) -> list[Path]:
    """The paths of one ``sequences`` entry: a path, or a glob (its folders and videos)."""
    full = Path(pattern).expanduser()
    full = full if full.is_absolute() else base / full
    if glob.has_magic(pattern):
        from pgm.io.video import natural_key

        hits = [Path(p) for p in glob.glob(str(full))]
        hits = [p for p in hits
                if p.is_dir() or (p.is_file() and p.suffix.lower() not in _SKIP_SUFFIXES)]
        if not hits:
            raise InputError(f"{where}: {pattern!r} matches no sequence folder or video "
                             f"(relative to {base})")
        return sorted(hits, key=lambda p: natural_key(str(p)))
    if not full.exists():
        raise InputError(f"{where}: no such file or folder: {pattern!r} (relative to {base})")
    return [full]


def _sequences(value: Any, base: Path, where: str) -> tuple[SequenceSpec, ...]:
    from pgm.io.video import open_source

    if value is None:
        raise InputError(f"{where}: no sequences (give sequences = [\"PATH\", \"GLOB\", ...])")
    entries = value if isinstance(value, list) else [value]
    if not entries:
        raise InputError(f"{where}: sequences is an empty list")
    out: list[SequenceSpec] = []
    by_name: dict[str, str] = {}
    for i, entry in enumerate(entries):
        here = f"{where}: sequences[{i}]"
        name = None
        if isinstance(entry, dict):
            unknown = sorted(set(entry) - {"path", "name"})
            if unknown:
                raise InputError(f"{here}: unknown key {unknown[0]!r} (a sequence table has "
                                 f"path and name)")
            pattern, name = entry.get("path"), entry.get("name")
            if name is not None and (not isinstance(name, str)
                                     or not _SAFE_NAME.fullmatch(name)):
                raise InputError(f"{here}: name must be letters, digits and . _ + = -, got "
                                 f"{name!r}")
        else:
            pattern = entry
        if not isinstance(pattern, str) or not pattern.strip():
            raise InputError(f"{here}: a sequence is a path or glob (a string) or a table "
                             f"{{path = \"...\", name = \"...\"}}, got {pattern!r}")
        paths = _candidates(pattern, base, here)
        if name is not None and len(paths) > 1:
            raise InputError(f"{here}: {pattern!r} matches {len(paths)} sequences; a name "
                             f"applies to one")
        for p in paths:
            resolved = str(p.resolve())
            if any(s.path == resolved for s in out):
                continue  # listed twice (a path and a glob): one run each
            try:
                source = open_source(resolved)
            except InputError as exc:
                raise InputError(f"{here}: {one_line(exc)}") from None
            seq_name = name or _safe_name(source.name)
            if seq_name in by_name:
                raise InputError(f"{here}: two sequences are named {seq_name!r} "
                                 f"({by_name[seq_name]} and {resolved}); give one its own "
                                 f"name: {{path = \"...\", name = \"...\"}}")
            by_name[seq_name] = resolved
            out.append(SequenceSpec(seq_name, resolved, source.gt_path is not None,
                                    source.det_path is not None))
    return tuple(out)


@functools.lru_cache(maxsize=16)
def _track_actions(model: str | None = None) -> dict[str, argparse.Action]:
    """``pgm track``'s options for ``model`` by destination (read from the parser with
    the model's own options, so that an option added to ``pgm track`` or declared by a
    model is an option of an experiment too)."""
    from pgm.app.cli import build_parser
    from pgm.models import get_config

    config = None
    if model is not None and not model.endswith(".json"):
        config = get_config(model)
    parser = build_parser(config)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest: a for a in sub.choices["track"]._actions}


def _option_tokens(key: str, value: Any, base: Path, where: str,
                   model: str | None = None) -> list[str]:
    """``pgm track`` arguments for one option of a model entry."""
    import difflib

    actions = _track_actions(model)
    dest = key.replace("-", "_")
    if dest in RESERVED_OPTIONS:
        raise InputError(f"{where}: {key!r} is not a per-model option (set by "
                         f"{RESERVED_OPTIONS[dest]})")
    action = actions.get(dest)
    if (action is None or not action.option_strings) and model is not None:
        from pgm.app.cli_track import explain_unknown_options

        other = explain_unknown_options(["--" + key.replace("_", "-")], model)
        if other is not None:
            raise InputError(f"{where}: {other}")
    if action is None or not action.option_strings:
        known = sorted(d.replace("_", "-") for d in actions if d not in RESERVED_OPTIONS)
        near = difflib.get_close_matches(key.replace("_", "-"), known, n=1)
        hint = f"; did you mean {near[0]!r}?" if near else f" (options: {', '.join(known)})"
        raise InputError(f"{where}: unknown option {key!r}{hint}")
    flag = next((s for s in action.option_strings if s.startswith("--")),
                action.option_strings[0])
    if action.nargs == 0:  # a flag
        if not isinstance(value, bool):
            raise InputError(f"{where}: {key} is a flag: true or false, got {value!r}")
        if isinstance(action, argparse.BooleanOptionalAction):
            return [flag if value else "--no-" + flag[2:]]
        if value == action.default:
            return []
        if value == bool(action.const):
            return [flag]
        raise InputError(f"{where}: {key} cannot be {str(value).lower()}")
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise InputError(f"{where}: {key} must be a string or a number, got {value!r}")
    text = str(value)
    if dest in PATH_OPTIONS:
        p = Path(text).expanduser()
        p = p if p.is_absolute() else base / p
        if not p.is_file():
            raise InputError(f"{where}: {key}: no such file: {text!r} (relative to {base})")
        text = str(p.resolve())
    converted: Any = text
    if callable(action.type):
        try:
            converted = action.type(text)
        except (argparse.ArgumentTypeError, ValueError, TypeError) as exc:
            raise InputError(f"{where}: {one_line(exc)}") from None
    if action.choices is not None and converted not in action.choices:
        raise InputError(f"{where}: {key} must be one of "
                         f"{', '.join(map(str, action.choices))}, got {value!r}")
    return [f"{flag}={text}"]


def _parse_track(argv: Sequence[str]) -> argparse.Namespace:
    """``pgm track``'s namespace of ``argv`` (``["track", ...]``); a parse error is an
    :class:`InputError` with the parser's one line."""
    from pgm.app.cli import parse_args

    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            return parse_args(list(argv))
    except SystemExit:
        msg = one_line(err.getvalue()).removeprefix("pgm: error: ")
        raise InputError(msg or f"bad arguments: {shlex.join(argv)}") from None


def _check_single_object(model: ModelSpec, where: str) -> None:
    """Build a single-object model's graph once, as ``pgm track`` will: an option that
    does not apply to it is an error now, not in every run."""
    from pgm.app.cli_track import GENERIC_MULTI_TARGET, graph_from_config
    from pgm.models.config import VideoInfo

    args = _parse_track(["track", "-", "--model", model.name, "--out", "-", *model.options])
    for opt in GENERIC_MULTI_TARGET:
        if getattr(args, opt, None) is not None:
            raise InputError(f"{where}: {opt.replace('_', '-')} applies to multi-target "
                             f"models, not to {model.name!r}")
    if args.model_config is None:  # a saved model: its factors are fixed
        return
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            graph_from_config(args.model_config, args, VideoInfo(
                init_box=(50.0, 50.0, 20.0, 30.0), particles=args.particles))
    except InputError as exc:
        raise InputError(f"{where}: {one_line(exc)}") from None


def _models(value: Any, base: Path, where: str) -> tuple[ModelSpec, ...]:
    from pgm.app import cli
    from pgm.models import get_config, model_names

    names = ", ".join(model_names())
    if value is None:
        raise InputError(f"{where}: no models (add a [[models]] table with name = \"...\")")
    if not isinstance(value, list) or not value or not all(isinstance(v, dict) for v in value):
        raise InputError(f"{where}: models must be [[models]] tables, each with a name")
    out: list[ModelSpec] = []
    for i, entry in enumerate(value):
        here = f"{where}: models[{i}]"
        name = entry.get("name")
        if not isinstance(name, str) or not name:
            raise InputError(f"{here}: name is missing (a model of "
                             f"{names}, or a saved model.json)")
        saved = name.endswith(".json")
        if saved:
            p = Path(name).expanduser()
            p = p if p.is_absolute() else base / p
            if not p.is_file():
                raise InputError(f"{here}: no such model file: {name!r} (relative to {base})")
            graph = cli.load_model_file(p)
            multi = graph.multi_target
            name = str(p.resolve())
            default_label = _safe_name(p.parent.name if p.stem == "model" else p.stem)
        elif name in model_names():
            try:
                config = get_config(name)
            except ValueError as exc:
                raise InputError(f"{here}: {one_line(exc)}") from None
            if config.kind == "state-space":
                raise InputError(f"{here}: model {name!r} runs on measurements, not on "
                                 f"video sequences")
            multi = config.kind == "multi-target"
            default_label = name
        else:
            raise InputError(f"{here}: unknown model {name!r} (choose from "
                             f"{names}, or a saved model.json)")
        label = entry.get("label", default_label)
        if not isinstance(label, str) or not _SAFE_NAME.fullmatch(label):
            raise InputError(f"{here}: label must be letters, digits and . _ + = -, got "
                             f"{label!r}")
        here = f"{where}: models[{i}] ({label})"
        if any(m.label == label for m in out):
            raise InputError(f"{here}: two models are labelled {label!r}; give each its own "
                             f"label = \"...\"")
        tokens: list[str] = []
        for key, opt in entry.items():
            if key not in ("name", "label"):
                tokens += _option_tokens(key, opt, base, here, name)
        detector = entry.get("detector")
        spec = ModelSpec(label, name, tuple(tokens), multi,
                         detector if isinstance(detector, str) else None)
        if not multi:
            _check_single_object(spec, here)
        elif "init" in entry:
            raise InputError(f"{here}: init does not apply to a multi-target model")
        out.append(spec)
    return tuple(out)


def _check_pairs(sequences: Sequence[SequenceSpec], models: Sequence[ModelSpec],
                 where: str) -> None:
    """Every model can run on every sequence: a single-object model starts from the
    sequence's ground truth, a model with public detections reads its ``det/det.txt``."""
    for s in sequences:
        for m in models:
            if not m.multi_target and not s.has_gt:
                raise InputError(f"{where}: sequence {s.name} ({s.path}) has no ground truth, "
                                 f"which the single-object model {m.label} needs for its "
                                 f"first box")
            public = m.detector is None or m.detector.strip().lower().startswith("public")
            if m.multi_target and public and not s.has_det:
                raise InputError(f"{where}: sequence {s.name} ({s.path}) has no det/det.txt "
                                 f"for the public detections of model {m.label}; set "
                                 f"detector = \"mog2\" or leave the sequence out")


def load_experiment(path: str | Path) -> Experiment:
    """Read and check an experiment file.

    Parameters
    ----------
    path : str or Path
        The TOML file; relative paths inside it are relative to its folder.

    Returns
    -------
    Experiment

    Raises
    ------
    InputError
        A missing or malformed file, an unknown key, model or option, a bad value, a
        path or glob that finds no sequence, bad seeds, or a model that cannot run on a
        sequence (one line naming the entry).
    """
    p = Path(path).expanduser()
    data = _read_toml(p)
    where = str(p)
    unknown = sorted(set(data) - set(TOP_LEVEL_KEYS))
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} (known: "
                         f"{', '.join(TOP_LEVEL_KEYS)})")
    base = p.resolve().parent
    name = data.get("name", p.stem)
    if not isinstance(name, str):
        raise InputError(f"{where}: name must be a string, got {name!r}")
    root = data.get("root_seed", 0)
    if not _is_int(root) or root < 0:
        raise InputError(f"{where}: root_seed must be an integer >= 0, got {root!r}")
    seeds = _seeds(data.get("seeds", 1), where)
    max_frames = data.get("max_frames")
    if max_frames is not None and (not _is_int(max_frames) or max_frames < 1):
        raise InputError(f"{where}: max_frames must be an integer >= 1, got {max_frames!r}")
    write_video = data.get("write_video", False)
    if not isinstance(write_video, bool):
        raise InputError(f"{where}: write_video must be true or false, got {write_video!r}")
    sequences = _sequences(data.get("sequences"), base, where)
    models = _models(data.get("models"), base, where)
    n_runs = len(sequences) * len(models) * len(seeds)
    if n_runs > MAX_RUNS:
        raise InputError(f"{where}: {len(sequences)} sequences × {len(models)} models × "
                         f"{len(seeds)} seeds is {n_runs} runs, more than an experiment may "
                         f"run ({MAX_RUNS} at most)")
    _check_pairs(sequences, models, where)
    return Experiment(p, name, root, seeds, max_frames, write_video, sequences, models)


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


@dataclass(frozen=True)
class RunSpec:
    """One run of an experiment: what a task needs (paths, never frames).

    Attributes
    ----------
    index : int
        Position in the table (by sequence, model, seed).
    sequence, source : str
        The sequence's name and absolute path.
    model, model_name : str
        The model's label and name (or saved-model path).
    options : tuple of str
        ``pgm track`` arguments of the model entry.
    seed : int
        The seed's label (its folder name).
    root_seed : int
    spawn_key : tuple of int
        ``(seed, sequence position, model position)``: see :func:`run_seed_sequence`.
    seed_int : int
        ``--seed`` of the run: :func:`run_seed_sequence` made a 64-bit integer.
    max_frames : int or None
    write_video : bool
    """

    index: int
    sequence: str
    source: str
    model: str
    model_name: str
    options: tuple[str, ...]
    seed: int
    root_seed: int
    spawn_key: tuple[int, ...]
    seed_int: int
    max_frames: int | None
    write_video: bool

    @property
    def label(self) -> str:
        """``sequence/model/seed``."""
        return f"{self.sequence}/{self.model}/{self.seed}"

    def folder(self, out: str | Path) -> Path:
        """``out/runs/<sequence>/<model>/<seed>``."""
        return Path(out) / "runs" / self.sequence / self.model / str(self.seed)

    def argv(self, out: str | Path) -> list[str]:
        """The run as ``pgm track`` arguments (without the program name)."""
        argv = ["track", self.source, "--model", self.model_name,
                "--out", str(self.folder(out)), "--seed", str(self.seed_int), "--quiet"]
        if not self.write_video:
            argv.append("--no-video")
        if self.max_frames is not None:
            argv += ["--max-frames", str(self.max_frames)]
        return argv + list(self.options)

    def record(self) -> dict[str, Any]:
        """What decides the run's result (``task.json`` holds it, and a finished run
        is reused only while the experiment still asks for the same)."""
        return {"sequence": self.sequence, "source": self.source, "model": self.model,
                "model_name": self.model_name, "options": list(self.options),
                "seed": self.seed, "root_seed": self.root_seed,
                "spawn_key": list(self.spawn_key), "seed_int": self.seed_int,
                "max_frames": self.max_frames, "write_video": self.write_video}


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


def _read_json(path: Path) -> dict[str, Any] | None:
    """The JSON object in ``path``, or None where it is missing or unreadable."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return data if isinstance(data, dict) else None


def run_state(run: RunSpec, out: str | Path) -> str:
    """``"complete"`` (finished, same settings), ``"changed"`` (finished with other
    settings), ``"incomplete"`` (started, not finished, or a result of a finished run
    has gone since: ``tracks.txt``, ``model.json``, or ``annotated.mp4`` when
    ``run.json`` says it wrote one) or ``"missing"``."""
    folder = run.folder(out)
    status = _read_json(folder / "run.json")
    if status is None:
        return "missing"
    if status.get("complete") is not True:
        return "incomplete"
    results = ["tracks.txt", "model.json"] + (["annotated.mp4"] if status.get("video") is True
                                              else [])
    if not all((folder / name).is_file() for name in results):
        return "incomplete"
    task = _read_json(folder / "task.json") or {}
    return "complete" if task.get("run") == run.record() else "changed"


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


def _run_processes(runs: Sequence[RunSpec], out: str, jobs: int) -> Iterator[Outcome]:
    """The local backend: one pool of ``jobs`` worker processes for all the runs, each
    worker started once with the toolkit imported (:func:`_worker_context`); outcomes
    as they finish; interrupted or closed early, it stops the runs in progress."""
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(max_workers=min(jobs, len(runs)) or 1,
                               mp_context=_worker_context(), initializer=_worker_init)
    futures = {pool.submit(run_task, run, out): run for run in runs}
    try:
        for fut in as_completed(futures):
            run = futures[fut]
            try:
                yield run, fut.result()
            except Exception as exc:  # noqa: BLE001 - a dead worker fails its run only
                yield run, {"status": "failed", "seconds": 0.0, "warnings": [],
                            "error": f"worker process failed: {type(exc).__name__}: "
                                     f"{one_line(exc)}"}
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
            for fut in distributed.as_completed(list(futures)):
                run = futures[fut]
                try:
                    yield run, fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost worker fails its run only
                    yield run, {"status": "failed", "seconds": 0.0, "warnings": [],
                                "error": f"Dask task failed: {type(exc).__name__}: "
                                         f"{one_line(exc)}"}
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# -- the table -------------------------------------------------------------------------------
def is_timing_column(name: str) -> bool:
    """Whether a column of ``results.csv`` measures time (frames per second, seconds),
    which no two executions repeat."""
    return name == "fps" or name.endswith("_fps") or name.endswith("seconds")


def _scalars(data: dict[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """The scalar entries of ``metrics.json``, nested tables as ``outer.inner``."""
    for key, value in data.items():
        name = prefix + str(key)
        if isinstance(value, dict):
            yield from _scalars(value, name + ".")
        elif isinstance(value, bool):
            yield name, int(value)
        elif value is None or isinstance(value, (int, float)):
            yield name, value


def collect_rows(runs: Sequence[RunSpec], out: str | Path) -> list[dict[str, Any]]:
    """One row per complete run of ``runs`` (in their order): ``sequence``, ``model``,
    ``seed``, every scalar of its ``metrics.json`` and ``fps`` (inference frames per
    second, from ``run.json``)."""
    rows = []
    for run in runs:
        if run_state(run, out) != "complete":
            continue
        folder = run.folder(out)
        status = _read_json(folder / "run.json") or {}
        metrics = _read_json(folder / "metrics.json") or {}
        row: dict[str, Any] = {"sequence": run.sequence, "model": run.model, "seed": run.seed}
        row.update((k, v) for k, v in _scalars(metrics) if k != "fps")
        row["fps"] = status.get("fps")
        rows.append(row)
    return rows


def _columns(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Every column of ``rows`` in order of first appearance, ``fps`` last."""
    cols: dict[str, None] = {}
    for row in rows:
        cols.update(dict.fromkeys(row))
    names = [c for c in cols if c != "fps"]
    return names + (["fps"] if "fps" in cols else [])


def _cell(value: Any) -> str:
    """A CSV cell: floats in full (``repr``), None empty."""
    return "" if value is None else repr(value) if isinstance(value, float) else str(value)


def _write_text(path: Path, text: str) -> None:
    """Write ``path`` whole or not at all (:func:`pgm.io.outputs.write_text`)."""
    from pgm.io.outputs import prepare_output_file, write_text

    prepare_output_file(path, "results file")
    write_text(path, text)


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([_cell(v) for v in row])
    _write_text(path, buf.getvalue())


def _stats(values: Sequence[Any]) -> tuple[int, float, float, float, float] | None:
    """``(n, mean, sample std, min, max)`` of the finite numbers, or None."""
    xs = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    if not xs:
        return None
    a = np.asarray(xs)
    std = float(a.std(ddof=1)) if a.size > 1 else 0.0
    return a.size, float(a.mean()), std, float(a.min()), float(a.max())


def _num(v: float) -> str:
    """A number for the markdown table: three significant digits, one decimal from 100."""
    if v == 0 or not math.isfinite(v):
        return f"{v:g}"
    return f"{v:.1f}" if abs(v) >= 100 else f"{v:.3g}"


def _summaries(rows: Sequence[dict[str, Any]], columns: Sequence[str]):
    """``{(sequence, model): {metric: stats}}`` in row order."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["sequence"], row["model"]), []).append(row)
    out = {}
    for key, members in groups.items():
        out[key] = {c: s for c in columns if c not in ("sequence", "model", "seed")
                    and (s := _stats([m.get(c) for m in members])) is not None}
    return out


def write_results(experiment: Experiment, runs: Sequence[RunSpec], out: str | Path) -> Path:
    """Write ``results.csv``, ``summary.csv`` and ``results.md`` from the complete runs
    on disk; returns the CSV's path."""
    out = Path(out)
    rows = collect_rows(runs, out)
    columns = _columns(rows)
    _write_csv(out / RESULTS_CSV, columns, [[r.get(c) for c in columns] for r in rows])
    summaries = _summaries(rows, columns)
    _write_csv(out / SUMMARY_CSV, ["sequence", "model", "metric", "n", "mean", "std", "min",
                                   "max"],
               [[s, m, metric, *stats] for (s, m), by in summaries.items()
                for metric, stats in by.items()])
    lines = [f"# Experiment {experiment.name}", "",
             f"{len(rows)} of {len(runs)} runs complete: "
             f"{_count(len(experiment.sequences), 'sequence')} × "
             f"{_count(len(experiment.models), 'model')} × "
             f"{_count(len(experiment.seeds), 'seed')} "
             f"(root seed {experiment.root_seed}"
             + (f", at most {experiment.max_frames} frames" if experiment.max_frames else "")
             + "). Each cell is the mean ± the sample standard deviation (ddof = 1) over "
               "the seeds; `n` is the number of seeds; min and max are in "
               f"`{SUMMARY_CSV}`, every run in `{RESULTS_CSV}`. `fps`: inference frames "
               "per second.", ""]
    models = [m.label for m in experiment.models]
    for seq in experiment.sequences:
        present = [m for m in models if (seq.name, m) in summaries]
        if not present:
            continue
        metrics: dict[str, None] = {}
        for m in present:
            metrics.update(dict.fromkeys(summaries[seq.name, m]))
        order = [c for c in columns if c in metrics]
        lines += [f"## {seq.name}", "", "| metric | " + " | ".join(present) + " |",
                  "| --- |" + " ---: |" * len(present)]
        n_row = [str(max(st[0] for st in summaries[seq.name, m].values()))
                 if summaries[seq.name, m] else "0" for m in present]
        lines.append("| n | " + " | ".join(n_row) + " |")
        for metric in order:
            cells = []
            for m in present:
                st = summaries[seq.name, m].get(metric)
                cells.append("" if st is None else
                             _num(st[1]) + (f" ± {_num(st[2])}" if st[0] > 1 else ""))
            lines.append(f"| {metric} | " + " | ".join(cells) + " |")
        lines.append("")
    _write_text(out / RESULTS_MD, "\n".join(lines))
    return out / RESULTS_CSV


# -- the experiment --------------------------------------------------------------------------
@dataclass
class ExperimentResult:
    """What :func:`run_experiment` did.

    Attributes
    ----------
    runs : list of RunSpec
        The whole grid.
    ran, skipped : list of RunSpec
        Runs executed now / found complete.
    failed : list of (RunSpec, str)
        Runs that failed, with the one-line error.
    rows : list of dict
        ``results.csv``'s rows.
    seconds : float
        Wall time.
    """

    runs: list[RunSpec]
    ran: list[RunSpec] = field(default_factory=list)
    skipped: list[RunSpec] = field(default_factory=list)
    failed: list[tuple[RunSpec, str]] = field(default_factory=list)
    rows: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0


def _count(n: int, word: str) -> str:
    """``"1 seed"``, ``"3 seeds"``."""
    return f"{n} {word}" + ("" if n == 1 else "s")


def _headline(folder: Path) -> str:
    """`` (success_auc 0.712)`` or `` (mota 0.41)`` for a run's progress line."""
    metrics = _read_json(folder / "metrics.json") or {}
    for key in ("success_auc", "mota"):
        value = metrics.get(key)
        if isinstance(value, (int, float)):
            return f" ({key} {value:.3f})"
    return ""


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
    return b


def cmd_bench(args: argparse.Namespace) -> int:
    """``pgm bench``: load, run, write the tables, print where they are."""
    experiment = load_experiment(args.experiment)
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
