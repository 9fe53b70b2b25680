"""``pgm bench`` experiment files: reading and checking the TOML (sequences, models, seeds)
before any run starts (:mod:`pgm.app.experiment`)."""

from __future__ import annotations

import argparse
import contextlib
import functools
import glob
import io
import logging
import re
import shlex
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pgm.core.errors import InputError, one_line

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
        from pgm.app.cli_args import explain_unknown_options

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


def _imports(value: Any, base: Path, where: str) -> list[str]:
    """A model entry's ``import = "FILE.py"`` (or a list, or module names): imported now
    (a saved model naming their factors loads) and given to every run as ``--import``."""
    from pgm.app.cli_args import import_user_code

    if value is None:
        return []
    items = value if isinstance(value, list) else [value]
    out = []
    for item in items:
        if not isinstance(item, str) or not item:
            raise InputError(f"{where}: import must be a .py file or a module name, got "
                             f"{item!r}")
        if item.endswith(".py"):
            p = Path(item).expanduser()
            p = p if p.is_absolute() else base / p
            if not p.is_file():
                raise InputError(f"{where}: import: no such file: {item!r} (relative to {base})")
            item = str(p.resolve())
        try:
            import_user_code(item)
        except InputError as exc:
            raise InputError(f"{where}: {one_line(exc)}") from None
        out.append(item)
    return out


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
        imports = _imports(entry.get("import"), base, here)  # the user's factors and rules
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
        tokens: list[str] = [f"--import={p}" for p in imports]
        for key, opt in entry.items():
            if key not in ("name", "label", "import"):
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
