"""``pgm bench`` results: the runs' metrics collected into ``results.csv`` and a summary
(:mod:`pgm.app.experiment`)."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .experiment_spec import RESULTS_CSV, RESULTS_MD, SUMMARY_CSV, Experiment, RunSpec


# -- the table -------------------------------------------------------------------------------
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
