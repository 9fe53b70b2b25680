"""``pgm report DIR``: one self-contained HTML page about the runs under a folder.

``DIR`` is one run folder (``tracks.txt``, ``metrics.json``, ``run.json``, ``model.json``
as ``pgm track`` writes them) or any folder holding many (at any depth, e.g.
``runs/<seq>/<model>/<seed>/`` as ``pgm bench`` writes them). :func:`write_report` finds
every folder holding a ``run.json`` or a ``metrics.json``, reads them and writes

* ``DIR/report.html`` — readable without JavaScript or network: inline CSS, every image a
  PNG embedded as a ``data:image/png;base64,`` URI;
* ``DIR/report_files/*.png`` — the same images as files (earlier ``*.png`` there are
  removed first).

Contents
--------
* a summary (one row per sequence and model);
* single-object runs: the OTB success plot (fraction of scored frames with IoU above
  each threshold, success AUC in the legend) and precision plot (fraction with centre
  error at most each distance, precision at 20 px in the legend), per sequence and
  overall (the mean of the per-sequence curves, as the OTB toolkit averages them);
* multi-target runs: bars of MOTA, IDF1, HOTA, MOTP, DetA, AssA and of the mean OSPA
  values per sequence and model (and their mean over sequences), and the per-frame OSPA
  and cardinality (truth against estimate) of each sequence from the ``per_frame``
  series of ``metrics.json``;
* frames per second of inference (``run.json``'s ``fps``: decoding, detection and
  drawing excluded);
* the factor graph of each model, drawn from its ``model.json``;
* every scalar metric, one table per sequence (rows: metrics; columns: models);
* every run found, and those left out (unfinished: ``run.json`` says
  ``"complete": false``).

Grouping
--------
A run's *sequence* is the last component of ``run.json``'s ``source`` (the folder above
``img``/``img1``/``imgs`` when the source is the image folder itself, the file name
without its suffix for a video); its *model* is ``run.json``'s ``model`` (the graph's
name). Runs sharing a sequence and model are the seeds of one configuration and are
averaged: the tables show ``mean ± standard deviation`` over seeds (``n - 1`` in the
denominator), the plots the mean curve with the seeds' range shaded. Runs of one
sequence and model that differ in length (``run.json``'s ``frames``) or settings
(particles, camera motion, dropped frames, ``model.json``'s engine settings) are not
seeds of one configuration: each gets the settings that differ in its label
(``colour-pf (50 frames)``), a row of its own, and the page and a warning say so. Runs
whose ``run.json`` records the same seed as well repeat one run: they are not seeds of
it and are not averaged (``colour-pf (seed 0, repeat 2)``, a row each). When
runs of one model name sit in differently named parent folders (two configurations of
one model, e.g. ``runs/<seq>/phd/`` and ``runs/<seq>/phd-scores/``), the parent
folder's name tells them apart.

Bad input — ``DIR`` missing or not a folder, no run under it, no finished run, a
``run.json`` or ``metrics.json`` that is not a JSON object, a malformed per-frame
series — is an :class:`~pgm.core.errors.InputError` naming the problem. A ``model.json``
that cannot be drawn is noted on the page, not an error.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

import numpy as np

from pgm.app.report_calibration import (  # noqa: F401  (names of this module since the split)
    _calibration,
    _calibration_section,
    _confidence_outcomes,
    _reliability_figure,
)
from pgm.app.report_figures import (  # noqa: F401  (names of this module since the split)
    MOT_SCORES,
    _colours,
    _figure,
    _fps_figure,
    _Images,
    _mot_figure,
    _ospa_keys,
    _ospa_label,
    _otb_figure,
    _per_frame_figure,
)
from pgm.app.report_html import (  # noqa: F401  (names of this module since the split)
    _CSS,
    _KIND_TITLES,
    METRIC_NAMES,
    SUMMARY_COLUMNS,
    _e,
    _img,
    _metric_name,
    _slug,
    _summary,
    _table,
)
from pgm.app.report_runs import (  # noqa: F401  (names of this module since the split)
    CONFIG_FIELDS,
    FILES_DIR,
    Group,
    Run,
    _assign_labels,
    _config,
    _describe,
    _group,
    _is_number,
    _numbers,
    _parent_name,
    _read_json,
    _sequence_name,
    find_runs,
    group_runs,
    load_run,
    split_configurations,
)
from pgm.app.report_stats import (  # noqa: F401  (names of this module since the split)
    Stat,
    _curve,
    _flatten,
    _fmt,
    _fmt3,
    _fmt_stat,
    _group_stats,
    _mean_curve,
    _scalars,
    _series,
    _stat,
)
from pgm.core.errors import InputError, one_line
from pgm.io.outputs import write_text

__all__ = ["Run", "Group", "find_runs", "load_run", "group_runs", "split_configurations",
           "write_report",
           "add_parser", "cmd_report", "COMMANDS", "REPORT_NAME", "FILES_DIR"]

REPORT_NAME = "report.html"
_log = logging.getLogger("pgm")


def _draw_model(run: Run, images: _Images, label: str) -> tuple[str, bytes] | str:
    """The drawing of a run's ``model.json``: (file name, PNG bytes), or a note why not."""
    from pgm.core.graph import FactorGraph

    path = run.model_file
    if path is None:
        return "no model.json in the run folder"
    try:
        graph = FactorGraph.load(path)
    except (ValueError, KeyError, TypeError, AttributeError, IndexError,
            RecursionError) as exc:
        return f"{path} could not be loaded: {one_line(exc)[:200]}"
    out = images.path_for(f"graph-{label}")
    try:
        graph.draw(out)
    except (ValueError, KeyError, TypeError) as exc:
        return f"{path} could not be drawn: {one_line(exc)[:200]}"
    images.names.add(out.name)
    return out.name, out.read_bytes()


def _prepare_files(root: Path) -> Path:
    folder = root / FILES_DIR
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise InputError(f"{folder} exists and is not a folder; remove it to write the "
                         f"report")
    try:
        folder.mkdir(exist_ok=True)
        for old in folder.glob("*.png"):
            if old.is_file() or old.is_symlink():
                old.unlink()
    except OSError as exc:
        raise InputError(f"cannot write {folder}: {exc.strerror or one_line(exc)}") from None
    return folder


def _load_all(root: Path) -> tuple[list[Run], list[Run]]:
    folders = find_runs(root)
    if not folders:
        raise InputError(f"no runs under {root}: no folder holds a run.json or metrics.json "
                         f"(written by 'pgm track' or 'pgm bench')")
    runs = [load_run(f, root) for f in folders]
    done = [r for r in runs if r.complete]
    left = [r for r in runs if not r.complete]
    if not done:
        raise InputError(f"no finished run under {root}: {len(runs)} run folder(s), each "
                         f"with run.json saying \"complete\": false")
    return done, left


def write_report(root: str | Path, title: str | None = None) -> Path:
    """Write ``root/report.html`` (and ``root/report_files/*.png``) about every run
    under ``root``; returns the HTML path.

    Parameters
    ----------
    root : path
        A run folder or a folder of runs (any depth).
    title : str, optional
        The page's heading (default: ``Tracking report — <root's name>``).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        ``root`` missing or not a folder, no run found, no finished run, a corrupt
        ``run.json`` or ``metrics.json``, or a folder that cannot be written.
    """
    import pgm

    base = Path(root)
    runs, left = _load_all(base)
    _assign_labels(runs)
    splits = split_configurations(runs)
    for line in splits:
        _log.warning("report: %s", line)
    groups = _group(runs)
    stats = {(g.sequence, g.label): _group_stats(g) for g in groups}
    labels = sorted({g.label for g in groups})
    colours = _colours(labels)
    sequences = sorted({g.sequence for g in groups})
    images = _Images(_prepare_files(base))
    heading = title or f"Tracking report — {base.resolve().name or base}"
    parts: list[str] = []
    toc: list[tuple[str, str]] = [("summary", "Summary")]

    # -- summary
    parts.append('<section id="summary"><h2>Summary</h2>' + _summary(groups, stats)
                 + '<p class="note">Several runs of one sequence and model (seeds) are '
                   "averaged: mean ± standard deviation over the runs. Runs that differ in "
                   "length or settings are not seeds of one configuration: they are "
                   "separate rows, labelled with what differs.</p>"
                 + "".join(f'<p class="note warning">{_e(line)}.</p>' for line in splits)
                 + "</section>")

    # -- single object
    single = [g for g in groups if g.kind == "single"]
    if single:
        toc.append(("single-object", "Single-object tracking (OTB plots)"))
        out = ['<section id="single-object"><h2>Single-object tracking</h2>',
               '<p class="note">Success plot: fraction of scored frames whose IoU with the '
               "ground truth exceeds the threshold; the legend gives the success AUC (mean "
               "over the 21 thresholds 0, 0.05, …, 1; a perfect track scores 20/21 ≈ 0.952, "
               "the OTB convention). Precision plot: fraction of frames whose centre error "
               "is at most the distance; the legend gives the precision at 20 px. Shading: "
               "range over seeds.</p>"]
        per_label: dict[str, list[dict[str, Any]]] = {}
        seq_blocks = []
        for seq in sequences:
            entries = []
            for g in (g for g in single if g.sequence == seq):
                runs_ = g.scored()
                st = stats[(g.sequence, g.label)]
                e = {"label": g.label, "colour": colours[g.label],
                     "success": _mean_curve(runs_, "success"),
                     "precision": _mean_curve(runs_, "precision"),
                     "auc": st["success_auc"].mean if "success_auc" in st else None,
                     "p20": st["precision_at_20"].mean if "precision_at_20" in st else None,
                     "band": True}
                entries.append(e)
                per_label.setdefault(g.label, []).append(e)
            if entries:
                fig = _otb_figure(entries, seq)
                name, data = images.save_figure(fig, f"otb-{seq}")
                seq_blocks.append(f'<h3 id="otb-{_slug(seq)}">{_e(seq)}</h3>'
                                  + _img(name, data, f"success and precision plots, {seq}"))
        overall = []
        for label, es in sorted(per_label.items()):
            curves = {}
            for kind in ("success", "precision"):
                cs = [e[kind] for e in es if e[kind] is not None]
                curves[kind] = None if not cs else {
                    "x": cs[0]["x"], "y": np.mean([c["y"] for c in cs], axis=0),
                    "lo": None, "hi": None, "n": len(cs)}
            aucs = [e["auc"] for e in es if e["auc"] is not None]
            p20s = [e["p20"] for e in es if e["p20"] is not None]
            overall.append({"label": f"{label} ({len(es)} seq)", "colour": colours[label],
                            "success": curves["success"], "precision": curves["precision"],
                            "auc": float(np.mean(aucs)) if aucs else None,
                            "p20": float(np.mean(p20s)) if p20s else None, "band": False})
        fig = _otb_figure(overall, f"overall ({len({g.sequence for g in single})} "
                                   f"sequence(s))")
        name, data = images.save_figure(fig, "otb-overall")
        out.append('<h3 id="otb-overall">Overall</h3>'
                   + _img(name, data, "overall success and precision plots",
                          "Mean over sequences of each model's per-sequence curves; AUC "
                          "and precision in the legend are the means of the per-sequence "
                          "values."))
        out += seq_blocks
        out.append("</section>")
        parts.append("".join(out))

    # -- confidence calibration (single-object models that report a confidence)
    section = _calibration_section(single, labels, colours, images)
    if section is not None:
        toc.append(("calibration", "Confidence calibration"))
        parts.append(section)

    # -- multi target
    multi = [g for g in groups if g.kind == "multi"]
    if multi:
        toc.append(("multi-target", "Multi-target tracking (MOT metrics, OSPA)"))
        out = ['<section id="multi-target"><h2>Multi-target tracking</h2>',
               '<p class="note">CLEAR MOT, identity and HOTA scores (higher is better; '
               "error bars: standard deviation over seeds) and mean set distances on box "
               "foot points (lower is better). Per-frame panels: OSPA between the ground "
               "truth and the estimate in each frame, and the number of targets (truth in "
               "black, each model's estimate in its colour), mean over seeds.</p>"]
        mseqs = [s for s in sequences if any(g.sequence == s for g in multi)]
        if len(mseqs) > 1:
            rows_ = []
            for label in labels:
                gs = [g for g in multi if g.label == label]
                if not gs:
                    continue
                keys = set().union(*(stats[(g.sequence, g.label)] for g in gs))
                mean_stats = {k: _stat([stats[(g.sequence, g.label)][k].mean
                                        for g in gs if k in stats[(g.sequence, g.label)]])
                              for k in keys}
                rows_.append((f"{label} ({len(gs)} seq)", colours[label], mean_stats))
            fig = _mot_figure(rows_, f"mean over {len(mseqs)} sequences")
            name, data = images.save_figure(fig, "mot-mean")
            out.append('<h3 id="mot-mean">Mean over sequences</h3>'
                       + _img(name, data, "MOT scores, mean over sequences",
                              "Unweighted mean of the per-sequence values; error bars: "
                              "standard deviation over sequences."))
        for seq in mseqs:
            gs = [g for g in multi if g.sequence == seq]
            fig = _mot_figure([(g.label, colours[g.label], stats[(g.sequence, g.label)])
                               for g in gs], seq)
            name, data = images.save_figure(fig, f"mot-{seq}")
            block = (f'<h3 id="mot-{_slug(seq)}">{_e(seq)}</h3>'
                     + _img(name, data, f"MOT scores, {seq}"))
            fig = _per_frame_figure(gs, colours, seq)
            if fig is None:
                block += ('<p class="note warn">No per-frame series in these runs\' '
                          "metrics.json (written before they were stored): run them again "
                          "to plot OSPA and cardinality per frame.</p>")
            else:
                name, data = images.save_figure(fig, f"ospa-{seq}")
                block += (f'<div id="ospa-{_slug(seq)}">'
                          + _img(name, data, f"per-frame OSPA and cardinality, {seq}")
                          + "</div>")
            out.append(block)
        out.append("</section>")
        parts.append("".join(out))

    # -- speed
    fps_rows = [(f"{g.sequence} · {g.label}", colours[g.label], stats[(g.sequence, g.label)]
                 ["fps"]) for g in groups if "fps" in stats[(g.sequence, g.label)]
                and stats[(g.sequence, g.label)]["fps"].mean is not None]
    if fps_rows:
        toc.append(("fps", "Frames per second"))
        fig = _fps_figure(fps_rows)
        name, data = images.save_figure(fig, "fps")
        parts.append('<section id="fps"><h2>Frames per second</h2>'
                     + _img(name, data, "frames per second per sequence and model",
                            "Inference only (engine steps): decoding, detection, drawing "
                            "and writing excluded; mean ± standard deviation over seeds.")
                     + "</section>")

    # -- models
    toc.append(("models", "Models (factor graphs)"))
    out = ['<section id="models"><h2>Models</h2><p class="note">The factor graph of each '
           "model as saved in its model.json: circles are variables, squares factors "
           "(coloured by kind), grey circles observations.</p><div class=\"graphs\">"]
    for label in labels:
        first = next(r for g in groups if g.label == label for r in g.runs)
        drawn = _draw_model(first, images, label)
        if isinstance(drawn, str):
            out.append(f'<figure><figcaption><b>{_e(label)}</b>: <span class="warn">'
                       f"{_e(drawn)}</span></figcaption></figure>")
        else:
            name, data = drawn
            out.append(_img(name, data, f"factor graph of {label}",
                            f"<b>{_e(label)}</b> — from {_e(first.rel)}/model.json"))
    out.append("</div></section>")
    parts.append("".join(out))

    # -- every scalar metric
    toc.append(("metrics", "Every scalar metric"))
    out = ['<section id="metrics"><h2>Every scalar metric</h2><p class="note">One table '
           "per sequence; each cell is the mean ± standard deviation over the model's runs "
           "(n in the heading); nested values (the confidence calibration) are dotted "
           "keys.</p>"]
    for seq in sequences:
        gs = [g for g in groups if g.sequence == seq]
        keys: list[str] = []
        for g in gs:
            keys += [k for k in stats[(g.sequence, g.label)] if k not in keys]
        head = ["metric", "key"] + [f"{_e(g.label)} (n={len(g.runs)})" for g in gs]
        rows = [[_metric_name(k), f"<code>{_e(k)}</code>"]
                + [_fmt_stat(stats[(g.sequence, g.label)][k])
                   if k in stats[(g.sequence, g.label)] else "–" for g in gs] for k in keys]
        out.append(f'<h3 id="metrics-{_slug(seq)}">{_e(seq)}</h3>'
                   + _table(head, rows, text_cols=2))
    out.append("</section>")
    parts.append("".join(out))

    # -- runs
    toc.append(("runs", "Runs"))
    rows = [[_e(r.rel), _e(r.sequence), _e(r.label), _e(r.kind),
             _fmt(r.info.get("frames") if _is_number(r.info.get("frames")) else None, True),
             _fmt(r.fps)] for g in groups for r in g.runs]
    out = ['<section id="runs"><h2>Runs</h2>',
           _table(["folder", "sequence", "model", "kind", "frames", "frames/s"], rows,
                  text_cols=4)]
    if left:
        out.append(f'<p class="note warn">Left out: {len(left)} unfinished run(s) '
                   f"(run.json says \"complete\": false).</p>")
        out.append(_table(["folder", "sequence", "model", "stopped"],
                          [[_e(r.rel), _e(r.sequence), _e(r.model),
                            _e(r.info.get("stopped", "–"))] for r in left], text_cols=4))
    out.append("</section>")
    parts.append("".join(out))

    nav = "".join(f'<li><a href="#{a}">{_e(t)}</a></li>' for a, t in toc)
    n_models = len(labels)
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_e(heading)}</title><style>{_CSS}</style></head><body><main>"
        f"<header><h1>{_e(heading)}</h1><p class=\"meta\">{len(runs)} run(s) of "
        f"{len(sequences)} sequence(s) and {n_models} model(s) under <code>{_e(base)}"
        f"</code>; pgm {_e(pgm.__version__)}.</p></header>"
        f'<nav id="contents"><h2>Contents</h2><ol>{nav}</ol></nav>'
        + "".join(parts)
        + '<footer>Written by <code>pgm report</code>. Images are embedded; the same PNGs '
          f"are in <code>{FILES_DIR}/</code> beside this page.</footer>"
          "</main></body></html>\n")
    path = base / REPORT_NAME
    write_text(path, page)
    return path


# --------------------------------------------------------------------------- CLI


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``pgm report`` to the ``pgm`` sub-commands."""
    p = subparsers.add_parser(
        "report", help="write DIR/report.html about the runs under DIR",
        description="Write DIR/report.html, a self-contained page (images embedded, no "
                    "JavaScript) about\nevery run under DIR (a run folder written by "
                    "'pgm track', or a folder of runs at any depth,\ne.g. 'pgm bench' "
                    "output): OTB success/precision plots, MOT metric bars, per-frame "
                    "OSPA\nand cardinality, frames per second, each model's factor graph "
                    "and every scalar metric,\nseeds averaged. The PNGs are also written "
                    "to DIR/report_files/.",
        epilog="examples:\n  pgm track ../shared/data/TUD-Campus --model phd --out runs/tud "
               "--no-video\n  pgm report runs/tud\n  pgm report bench_out/   # every run "
               "under it")
    from pgm.app.cli import _path

    p.add_argument("dir", type=_path("DIR"), metavar="DIR",
                   help="a run folder or a folder of runs")
    p.add_argument("--title", default=None,
                   help="heading of the page (default: 'Tracking report — <DIR name>')")
    return p


def cmd_report(args) -> int:
    """``pgm report DIR``: write the report and say where."""
    path = write_report(args.dir, title=args.title)
    print(f"wrote {path} (images also in {path.parent / FILES_DIR})")
    return 0


COMMANDS = {"report": cmd_report}
