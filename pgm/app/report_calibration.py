"""``pgm report``: the confidence calibration section (:mod:`pgm.app.report`): how well
the per-frame confidence of single-object models predicts an overlap with the truth of at
least half (IoU ≥ 0.5), every sequence weighted equally; a reliability diagram and a
table."""

from __future__ import annotations

from typing import Any

import numpy as np

from pgm.app.report_figures import _figure, _Images
from pgm.app.report_html import _e, _img, _table
from pgm.app.report_runs import Group, Run, _numbers
from pgm.app.report_stats import _fmt3
from pgm.core.errors import InputError


def _confidence_outcomes(run: Run) -> tuple[np.ndarray, np.ndarray] | None:
    """A run's confidence and outcome (IoU ≥ 0.5) at its scored frames, or None where
    its ``metrics.json`` holds no per-frame confidence."""
    from pgm.evaluation.calibration import confidence_outcomes

    m = run.metrics or {}
    conf = m.get("confidence")
    if not isinstance(conf, dict) or "values" not in conf or "ious" not in m:
        return None
    where = run.path / "metrics.json"
    values = _numbers(conf["values"], f"{where}: confidence.values")
    if np.any(~np.isfinite(values) | (values < 0) | (values > 1)):
        raise InputError(f"{where} is corrupt: confidence.values must lie in [0, 1]")
    try:
        c, hit = confidence_outcomes(_numbers(conf.get("frames"), f"{where}: confidence.frames"),
                                     values, _numbers(m.get("frames"), f"{where}: frames"),
                                     _numbers(m["ious"], f"{where}: ious"))
    except ValueError as exc:
        raise InputError(f"{where} is corrupt: {exc}") from None
    return (c, hit) if c.size else None


def _calibration(runs: list[Run]) -> dict[str, Any] | None:
    """The reliability of the confidence of ``runs`` (one model) pooled with every
    sequence weighted equally (its seeds share its weight), and the mean over sequences
    of each sequence's own ECE; None where no run has a confidence."""
    from pgm.evaluation.calibration import reliability, video_weights

    per_seq: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for r in runs:
        co = _confidence_outcomes(r)
        if co is not None:
            per_seq.setdefault(r.sequence, []).append(co)
    if not per_seq:
        return None
    # each sequence's seeds together: (confidence, outcome)
    joined = {q: tuple(np.concatenate(part) for part in zip(*cos, strict=True))
              for q, cos in per_seq.items()}
    c = np.concatenate([cy[0] for cy in joined.values()])
    y = np.concatenate([cy[1] for cy in joined.values()])
    who = np.concatenate([[q] * len(cy[0]) for q, cy in joined.items()])
    return {"pooled": reliability(c, y, weights=video_weights(who)), "sequences": len(joined),
            "runs": sum(map(len, per_seq.values())),
            "mean_sequence_ece": float(np.mean([reliability(*cy)["ece"]
                                                for cy in joined.values()]))}


def _reliability_figure(entries: list[tuple[str, Any, dict[str, Any]]]):
    """Reliability diagram: per model (``entries``: label, colour, calibration), each
    confidence bin's hit rate against its mean confidence, marker area ∝ the bin's
    share; the diagonal is a calibrated confidence."""
    fig = _figure(5.5, 4.6)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], color="#888", ls="--", lw=1, label="calibrated")
    for label, colour, cal in entries:
        bins = cal["pooled"]["bins"]
        x = [b["confidence"] for b in bins]
        y = [b["hit_rate"] for b in bins]
        ax.plot(x, y, color=colour, lw=1.5,
                label=f"{label} [{_fmt3(cal['pooled']['ece'])}]")
        ax.scatter(x, y, s=[20 + 400 * b["share"] for b in bins], color=colour, alpha=0.7,
                   edgecolors="none")
    ax.set(xlim=(0, 1), ylim=(-0.02, 1.02), xlabel="confidence (bin mean)",
           ylabel="hit rate (IoU ≥ 0.5)", title="Reliability, sequences weighted equally")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, title="ECE", title_fontsize=8)
    return fig


def _calibration_section(single: list[Group], labels: list[str], colours: dict[str, Any],
                         images: _Images) -> str | None:
    """The page's section on the confidence of the single-object groups ``single``
    (one entry per model label that reports a confidence), or None where none does."""
    cal_entries = [(label, colours[label], cal) for label in labels
                   if (cal := _calibration([r for g in single if g.label == label
                                             for r in g.scored()])) is not None]
    if not cal_entries:
        return None
    fig = _reliability_figure(cal_entries)
    name, data = images.save_figure(fig, "calibration")
    rows = [[_e(label), str(cal["sequences"]), str(cal["runs"]), str(cal["pooled"]["n"]),
             _fmt3(cal["pooled"]["ece"]), _fmt3(cal["pooled"]["brier"]),
             _fmt3(cal["pooled"]["mean_confidence"]), _fmt3(cal["pooled"]["hit_rate"]),
             _fmt3(cal["mean_sequence_ece"])] for label, _, cal in cal_entries]
    return (
        '<section id="calibration"><h2>Confidence calibration</h2>'
        '<p class="note">A model that writes a confidence per frame claims the '
        "probability that its box overlaps the truth by at least half (IoU ≥ 0.5). "
        "Frames are binned by confidence (10 bins) and each bin's hit rate is set "
        "against its mean confidence, pooled over the model's sequences with every "
        "sequence weighted equally (its seeds share its weight): what the confidence "
        "means on a frame of a sequence drawn at random. ECE: the weighted mean gap "
        "between confidence and hit rate; per sequence: the mean over sequences of "
        "each one's own ECE (a sequence can be over-confident where another is "
        "under-confident).</p>"
        + _img(name, data, "reliability diagram of the confidence")
        + _table(["model", "sequences", "runs", "frames", "ECE", "Brier",
                  "mean confidence", "hit rate", "ECE per sequence (mean)"], rows)
        + "</section>")
