"""``pgm report``: finding, reading and grouping the run folders under the report's root
(:mod:`pgm.app.report`): a :class:`Run` per folder holding a ``run.json`` or a
``metrics.json``, a :class:`Group` per (sequence, model label), runs of one label that
differ in length or settings told apart (:func:`split_configurations`)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError, one_line

#: the folder of the report's images (skipped when looking for runs)
FILES_DIR = "report_files"
_IMAGE_DIRS = ("img", "img1", "imgs")
_VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".mpg", ".mpeg", ".m4v", ".wmv")


def _read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; anything else is an :class:`InputError`."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or one_line(exc)}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path} is corrupt: not UTF-8 text") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is corrupt: not valid JSON ({exc.msg} at line "
                         f"{exc.lineno})") from None
    except RecursionError:
        raise InputError(f"{path} is corrupt: JSON nested too deeply") from None
    if not isinstance(data, dict):
        raise InputError(f"{path} is corrupt: expected a JSON object, found "
                         f"{type(data).__name__}")
    return data


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _numbers(value: Any, where: str) -> np.ndarray:
    """A 1-D float array from a JSON list (``None`` → NaN); an :class:`InputError`
    naming ``where`` otherwise."""
    if not isinstance(value, list) or not all(v is None or _is_number(v) for v in value):
        raise InputError(f"{where} is corrupt: expected a list of numbers")
    return np.array([np.nan if v is None else float(v) for v in value], dtype=float)


def _sequence_name(source: Any, folder: Path) -> str:
    if not isinstance(source, str) or not source.strip():
        return folder.name or "unknown"
    p = Path(source.rstrip("/\\"))
    if p.name.lower() in _IMAGE_DIRS and p.parent.name:
        return p.parent.name
    if p.suffix.lower() in _VIDEO_SUFFIXES:
        return p.stem
    return p.name or source


@dataclass
class Run:
    """One run folder as read by :func:`load_run`.

    Attributes
    ----------
    path : Path
        The folder.
    rel : str
        Its path relative to the report's root (``"."`` for the root itself).
    info : dict
        ``run.json`` (empty when the folder has none).
    metrics : dict or None
        ``metrics.json`` (None when the run had no ground truth).
    sequence, model : str
        The names it is grouped by (see the module docstring).
    label : str
        The model's name in the report (``model``, or told apart by the parent folder).
    """

    path: Path
    rel: str
    info: dict[str, Any]
    metrics: dict[str, Any] | None
    sequence: str
    model: str
    label: str = ""

    @property
    def complete(self) -> bool:
        """False when ``run.json`` says the run did not finish."""
        return bool(self.info.get("complete", True)) if self.info else self.metrics is not None

    @property
    def kind(self) -> str:
        """``"single"`` (OTB metrics), ``"multi"`` (MOT metrics) or ``"unscored"``."""
        m = self.metrics or {}
        if "mota" in m:
            return "multi"
        if "success_auc" in m or "ious" in m:
            return "single"
        return "unscored"

    @property
    def fps(self) -> float | None:
        """Frames per second of inference (``run.json``, else ``metrics.json``)."""
        for src in (self.info, self.metrics or {}):
            v = src.get("fps")
            if _is_number(v) and math.isfinite(v):
                return float(v)
        return None

    @property
    def model_file(self) -> Path | None:
        """``model.json`` when the folder has one."""
        p = self.path / "model.json"
        return p if p.is_file() else None


def find_runs(root: str | Path) -> list[Path]:
    """Every folder under ``root`` (itself included, any depth, symbolic links not
    followed, hidden folders and ``report_files`` skipped) holding a ``run.json`` or a
    ``metrics.json``, sorted.

    Raises
    ------
    InputError
        ``root`` missing or not a folder.
    """
    base = Path(root)
    if not base.exists():
        raise InputError(f"{base}: no such folder")
    if not base.is_dir():
        raise InputError(f"{base} is not a folder (give a run folder or a folder of runs)")
    found = []
    for dirpath, dirnames, filenames in os.walk(base):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".") and d != FILES_DIR)
        if "run.json" in filenames or "metrics.json" in filenames:
            found.append(Path(dirpath))
    return sorted(found)


def load_run(folder: str | Path, root: str | Path | None = None) -> Run:
    """Read one run folder (``run.json``, ``metrics.json``; ``model.json``'s name when
    ``run.json`` has none).

    Raises
    ------
    InputError
        A ``run.json`` or ``metrics.json`` that is not a JSON object.
    """
    path = Path(folder)
    info = _read_json(path / "run.json") if (path / "run.json").is_file() else {}
    metrics = _read_json(path / "metrics.json") if (path / "metrics.json").is_file() else None
    model = info.get("model")
    if not isinstance(model, str) or not model:
        model = None
        if (path / "model.json").is_file():
            try:
                name = json.loads((path / "model.json").read_text(encoding="utf-8")).get("name")
                model = name if isinstance(name, str) and name else None
            except (OSError, ValueError, AttributeError, RecursionError):
                model = None
        model = model or path.name or "model"
    rel = "." if root is None else (os.path.relpath(path, root) or ".")
    return Run(path, rel, info, metrics, _sequence_name(info.get("source"), path), model)


@dataclass
class Group:
    """The runs of one (sequence, model label): the seeds of one configuration."""

    sequence: str
    label: str
    runs: list[Run] = field(default_factory=list)

    @property
    def kind(self) -> str:
        """``"multi"`` if any run has MOT metrics, else ``"single"`` if any has OTB
        metrics, else ``"unscored"``."""
        kinds = {r.kind for r in self.runs}
        return "multi" if "multi" in kinds else "single" if "single" in kinds else "unscored"

    def scored(self) -> list[Run]:
        """The runs whose metrics are of the group's kind."""
        return [r for r in self.runs if r.kind == self.kind]


def _assign_labels(runs: list[Run]) -> None:
    parents: dict[str, set[str]] = {}
    for r in runs:
        parents.setdefault(r.model, set()).add(_parent_name(r))
    for r in runs:
        parent = _parent_name(r)
        if len(parents[r.model]) <= 1 or not parent:
            r.label = r.model
        else:
            r.label = parent if r.model in parent else f"{r.model} ({parent})"


def _parent_name(r: Run) -> str:
    """The name of the folder above the run, relative to the root ('' at the root)."""
    parent = Path(r.rel).parent
    return "" if r.rel == "." or str(parent) in ("", ".") else parent.name


#: ``run.json`` fields that make two runs of one model different configurations (not
#: seeds of one): how many frames were tracked and the settings the runner recorded
CONFIG_FIELDS = ("frames", "num_particles", "camera_motion", "dropped_frames")


def _config(run: Run) -> dict[str, str]:
    """What a run was run with, each value as compact JSON: the :data:`CONFIG_FIELDS` of
    ``run.json`` (``frames`` from ``metrics.json``'s ``n_frames`` when it has none) and
    the engine settings of ``model.json``."""
    out = {k: run.info[k] for k in CONFIG_FIELDS if k in run.info}
    if "frames" not in out and _is_number((run.metrics or {}).get("n_frames")):
        out["frames"] = run.metrics["n_frames"]
    if run.model_file is not None:
        try:
            meta = json.loads(run.model_file.read_text(encoding="utf-8")).get("meta")
            engine = meta.get("engine") if isinstance(meta, dict) else None
        except (OSError, ValueError, AttributeError, RecursionError):
            engine = None
        if isinstance(engine, dict):
            out["engine"] = engine
    return {k: json.dumps(v, sort_keys=True, separators=(",", ":")) for k, v in out.items()}


def _describe(key: str, text: str) -> str:
    """One differing setting, in words: ``50 frames``, ``particles 100``."""
    value = json.loads(text)
    if key == "frames":
        return f"{value} frames"
    if key == "num_particles" and isinstance(value, dict) and len(set(
            map(str, value.values()))) == 1:
        value = next(iter(value.values()))
    if key == "dropped_frames" and isinstance(value, list):
        return f"{len(value)} frames dropped"
    name = {"num_particles": "particles", "camera_motion": "camera motion"}.get(key, key)
    if isinstance(value, (dict, list)):
        value = text
    return f"{name} {value}"


def _by_label(runs: list[Run]) -> list[tuple[tuple[str, str], list[Run]]]:
    """The runs grouped by (sequence, label), sorted by it."""
    by_key: dict[tuple[str, str], list[Run]] = {}
    for r in runs:
        by_key.setdefault((r.sequence, r.label), []).append(r)
    return sorted(by_key.items())


def split_configurations(runs: list[Run]) -> list[str]:
    """Tell apart runs of one sequence and label that are not seeds of one configuration
    (a 300-frame and a 50-frame run; other particle counts or engine settings): each
    such run's label gets the settings that differ, e.g. ``colour-pf (50 frames)``, so
    they are separate rows, never averaged. Returns one line per (sequence, label) split.
    """
    notes = []
    for (sequence, label), members in _by_label(runs):
        configs = [_config(r) for r in members]
        keys = sorted({k for c in configs for k in c})
        differing = [k for k in keys if len({c.get(k) for c in configs}) > 1]
        if not differing:
            continue
        if "engine" in differing:  # name the engine settings that differ, not all of them
            engines = [json.loads(c.get("engine", "{}")) for c in configs]
            sub = sorted({k for e in engines for k in e
                          if len({json.dumps(e.get(k), sort_keys=True) for e in engines}) > 1})
            for c, e in zip(configs, engines, strict=True):
                c.update({f"engine.{k}": json.dumps(e.get(k), sort_keys=True) for k in sub})
            differing = [k for k in differing if k != "engine"] + [f"engine.{k}" for k in sub]
        for r, c in zip(members, configs, strict=True):
            words = [_describe(k, c[k]) for k in differing if k in c]
            r.label = f"{label} ({', '.join(words)})" if words else label
        notes.append(f"{sequence}, {label}: {len(members)} runs differ in "
                     f"{', '.join(k.replace('_', ' ') for k in differing)}; shown as "
                     f"{len({r.label for r in members})} rows, not averaged")
    return notes + _split_repeats(runs)


def _split_repeats(runs: list[Run]) -> list[str]:
    """Runs of one sequence, label and configuration that record the same seed are
    repeats of one run, not seeds: each gets ``(seed S, repeat k)`` in its label and a row
    of its own. Runs that record no seed (before ``run.json`` had one) are taken as seeds,
    as they always were."""
    notes = []
    for (sequence, label), members in _by_label(runs):
        seeds = [r.info.get("seed") for r in members]
        if any(not isinstance(s, int) or isinstance(s, bool) for s in seeds):
            continue
        repeated = sorted({s for s in seeds if seeds.count(s) > 1})
        if not repeated:
            continue
        count: dict[int, int] = {}
        for r, s in zip(members, seeds, strict=True):
            if s in repeated:
                count[s] = count.get(s, 0) + 1
                r.label = f"{label} (seed {s}, repeat {count[s]})"
        notes.append(f"{sequence}, {label}: runs with seed "
                     f"{', '.join(map(str, repeated))} repeat one run (the seed is the same), "
                     f"so they are not averaged as seeds; shown as rows of their own")
    return notes


def group_runs(runs: Iterable[Run]) -> list[Group]:
    """Runs grouped by (sequence, label), sorted; labels assigned on the way (runs of one
    label that differ in length or settings get distinct labels:
    :func:`split_configurations`)."""
    runs = list(runs)
    _assign_labels(runs)
    split_configurations(runs)
    return _group(runs)


def _group(runs: list[Run]) -> list[Group]:
    groups: dict[tuple[str, str], Group] = {}
    for r in runs:
        groups.setdefault((r.sequence, r.label), Group(r.sequence, r.label)).runs.append(r)
    return [groups[k] for k in sorted(groups)]
