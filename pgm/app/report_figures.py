"""``pgm report``: the figures (:mod:`pgm.app.report`): OTB success and precision plots,
MOT score bars, per-frame OSPA and cardinality, frames per second; each a matplotlib
figure, rendered to PNG by :class:`_Images`."""

from __future__ import annotations

import io
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from pgm.app.report_runs import Group
from pgm.app.report_stats import Stat, _fmt3, _series

#: scores in [0, 1] drawn as MOT bars (higher is better)
MOT_SCORES = (("MOTA", "mota"), ("IDF1", "idf1"), ("HOTA", "hota"), ("MOTP", "motp"),
              ("DetA", "deta"), ("AssA", "assa"))


class _Images:
    """PNG images written to ``report_files/`` and kept for embedding."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.names: set[str] = set()

    def _name(self, stem: str) -> str:
        base = re.sub(r"[^A-Za-z0-9._-]+", "-", stem).strip("-.") or "figure"
        name, k = f"{base}.png", 2
        while name in self.names:
            name, k = f"{base}-{k}.png", k + 1
        self.names.add(name)
        return name

    def save_figure(self, fig, stem: str) -> tuple[str, bytes]:
        """Render a matplotlib figure to PNG, write it; returns its file name and bytes."""
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
        data = buf.getvalue()
        name = self._name(stem)
        (self.folder / name).write_bytes(data)
        return name, data

    def path_for(self, stem: str) -> Path:
        """A fresh file path for an image written by someone else (the graph drawing)."""
        return self.folder / self._name(stem)


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def _colours(labels: list[str]) -> dict[str, Any]:
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return {label: cmap(i % 10) for i, label in enumerate(labels)}


def _otb_figure(entries: list[dict[str, Any]], title: str):
    """Success and precision plots side by side; ``entries``: label, colour, success,
    precision (mean curves), auc, p20, band (shade the seeds' range)."""
    fig = _figure(10.5, 4.0)
    ax_s, ax_p = fig.subplots(1, 2)
    for ax, curve, score in ((ax_s, "success", "auc"), (ax_p, "precision", "p20")):
        for e in sorted(entries, key=lambda e: -(e[score] or 0.0)):
            c = e[curve]
            if c is None:
                continue
            ax.plot(c["x"], c["y"], color=e["colour"], lw=2,
                    label=f"{e['label']} [{_fmt3(e[score])}]")
            if e["band"] and c["n"] > 1:
                ax.fill_between(c["x"], c["lo"], c["hi"], color=e["colour"], alpha=0.15, lw=0)
    ax_s.set(xlim=(0, 1), ylim=(0, 1.02), xlabel="overlap threshold (IoU)",
             ylabel="success rate", title=f"Success plot — {title}")
    ax_p.set(xlim=(0, 50), ylim=(0, 1.02), xlabel="location error threshold (px)",
             ylabel="precision", title=f"Precision plot — {title}")
    ax_p.axvline(20, color="#888", ls=":", lw=1)
    for ax, where, head in ((ax_s, "lower left", "success AUC"),
                            (ax_p, "lower right", "precision @ 20 px")):
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:  # not the 20 px marker alone
            ax.legend(loc=where, fontsize=8, title=head, title_fontsize=8)
    return fig


def _ospa_keys(keys: Iterable[str]) -> list[str]:
    return [k for k in keys if k.startswith("ospa_") and not k.endswith(("_loc", "_card"))]


def _ospa_label(key: str) -> str:
    if key == "ospa2":
        return "OSPA⁽²⁾"
    parts = key[len("ospa_"):].split("_")
    return f"OSPA({','.join(p.replace('p', '.') for p in parts)})"


def _mot_figure(rows: list[tuple[str, Any, dict[str, Stat]]], title: str):
    """Bars of the MOT scores and mean OSPA values; ``rows``: (label, colour, stats)."""
    fig = _figure(10.5, 3.8)
    ax_s, ax_d = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2, 1]})
    width = 0.8 / max(len(rows), 1)
    dist_keys = []
    for _, _, stats in rows:
        dist_keys += [k for k in _ospa_keys(stats) + ["ospa2"] if k in stats
                      and k not in dist_keys]
    for i, (label, colour, stats) in enumerate(rows):
        for ax, keys in ((ax_s, [k for _, k in MOT_SCORES]), (ax_d, dist_keys)):
            x = np.arange(len(keys)) + (i - (len(rows) - 1) / 2) * width
            mean = [stats[k].mean if k in stats and stats[k].mean is not None else np.nan
                    for k in keys]
            err = [stats[k].std if k in stats and stats[k].std is not None else 0.0
                   for k in keys]
            ax.bar(x, mean, width, yerr=err if any(err) else None, color=colour,
                   label=label if ax is ax_s else None, capsize=2,
                   error_kw={"lw": 0.8})
    ax_s.set_xticks(np.arange(len(MOT_SCORES)), [n for n, _ in MOT_SCORES])
    ax_s.axhline(0, color="#444", lw=0.8)
    ax_s.set(ylim=(min(0.0, ax_s.get_ylim()[0]), 1.0), ylabel="score (higher is better)",
             title=f"MOT scores — {title}")
    ax_d.set_xticks(np.arange(len(dist_keys)), [_ospa_label(k) for k in dist_keys])
    ax_d.set(ylabel="px (lower is better)", title="mean set distances")
    for ax in (ax_s, ax_d):
        ax.grid(axis="y", alpha=0.3)
    ax_s.legend(fontsize=8, loc="upper right", ncols=min(len(rows), 3))
    return fig


def _per_frame_figure(groups: list[Group], colours: dict[str, Any], title: str):
    """Per-frame OSPA (one panel per setting) and cardinality of one sequence."""
    keys: list[str] = []
    for g in groups:
        for r in g.scored():
            pf = (r.metrics or {}).get("per_frame")
            if isinstance(pf, dict):
                keys += [k for k in _ospa_keys(pf) + ["ospa2"] if k in pf and k not in keys]
    if not keys:
        return None
    fig = _figure(10.5, 1.9 * (len(keys) + 1) + 0.4)
    axes = fig.subplots(len(keys) + 1, 1, sharex=True)
    gt_done = False
    for g in groups:
        runs = g.scored()
        colour = colours[g.label]
        for ax, key in zip(axes[:-1], keys, strict=True):
            s = _series(runs, key)
            if s is not None:
                ax.plot(s[0], s[1], color=colour, lw=1.2, label=g.label)
        est = _series(runs, "pred_cardinality")
        if not gt_done:
            gt = _series(runs, "gt_cardinality")
            if gt is not None:
                axes[-1].step(gt[0], gt[1], where="mid", color="black", lw=2.2,
                              label="ground truth")
                gt_done = True
        if est is not None:
            axes[-1].step(est[0], est[1], where="mid", color=colour, lw=1.2,
                          label=f"{g.label} (estimate)")
    for ax, key in zip(axes[:-1], keys, strict=True):
        ax.set_ylabel(f"{_ospa_label(key)} px")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"Per-frame OSPA and cardinality — {title}")
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set(ylabel="targets", xlabel="frame")
    axes[-1].grid(alpha=0.3)
    axes[-1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig


def _fps_figure(rows: list[tuple[str, Any, Stat]]):
    """Horizontal bars of frames per second; ``rows``: (text, colour, stat)."""
    fig = _figure(9.0, 0.32 * len(rows) + 1.3)
    ax = fig.subplots()
    y = np.arange(len(rows))[::-1]
    means = np.array([s.mean for _, _, s in rows], dtype=float)
    err = [s.std or 0.0 for _, _, s in rows]
    ax.barh(y, means, xerr=err if any(err) else None, color=[c for _, c, _ in rows],
            capsize=2, error_kw={"lw": 0.8})
    ax.set_yticks(y, [t for t, _, _ in rows], fontsize=8)
    if means.size and means.min() > 0 and means.max() / means.min() > 50:
        ax.set_xscale("log")
    for yi, m, e in zip(y, means, err, strict=True):
        ax.text(m + e, yi, f"  {m:.0f}" if m >= 100 else f"  {m:.3g}", va="center",
                fontsize=8)
    if ax.get_xscale() == "linear":
        ax.set_xlim(0, float(np.max(means + np.asarray(err))) * 1.12)
    ax.set(xlabel="frames per second (inference only)", title="Speed")
    ax.grid(axis="x", alpha=0.3)
    return fig
