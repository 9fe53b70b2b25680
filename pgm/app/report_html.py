"""``pgm report``: the page's building blocks (:mod:`pgm.app.report`): its style, escaping,
embedded images, tables, metric names and the summary tables."""

from __future__ import annotations

import base64
import html
import re
from typing import Any

from pgm.app.report_figures import _ospa_label
from pgm.app.report_runs import FILES_DIR, Group
from pgm.app.report_stats import Stat, _fmt_stat

#: metric keys shown with a friendlier name (others show their key)
METRIC_NAMES = {
    "success_auc": "success AUC", "precision_at_20": "precision @ 20 px",
    "mean_iou": "mean IoU", "mean_centre_error": "mean centre error (px)",
    "median_centre_error": "median centre error (px)", "n_frames": "frames scored",
    "n_missing": "frames without a box", "fps": "frames per second",
    "mota": "MOTA", "motp": "MOTP (IoU)", "idf1": "IDF1", "idp": "IDP", "idr": "IDR",
    "hota": "HOTA", "deta": "DetA", "assa": "AssA", "loca": "LocA",
    "id_switches": "ID switches", "fragmentations": "fragmentations",
    "fp": "false positives", "fn": "false negatives", "tp": "true positives",
    "mostly_tracked": "mostly tracked", "partially_tracked": "partially tracked",
    "mostly_lost": "mostly lost", "ospa2": "OSPA⁽²⁾ (px)", "ospa2_window": "OSPA⁽²⁾ window",
    "mean_abs_cardinality_error": "|cardinality error|", "error_rate": "error rate",
    "num_gt": "ground-truth boxes", "num_pred": "predicted boxes",
    "num_frames": "frames scored", "detector_fps": "detector frames per second",
    "run.frames": "frames processed", "num_gt_ignored": "ground-truth rows ignored",
    "num_pred_ignored": "predictions on ignore regions",
    "confidence.calibration.n": "confidence: frames calibrated",
    "confidence.calibration.ece": "confidence: expected calibration error",
    "confidence.calibration.brier": "confidence: Brier score",
    "confidence.calibration.mean_confidence": "confidence: mean",
    "confidence.calibration.hit_rate": "confidence: hit rate (IoU ≥ 0.5)",
}

_CSS = """
:root { --ink: #1f2328; --muted: #59636e; --line: #d1d9e0; --band: #f6f8fa;
        --accent: #0969da; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto,
       "Helvetica Neue", Arial, sans-serif; color: var(--ink); background: #fff; }
main { max-width: 1180px; margin: 0 auto; padding: 24px 28px 64px; }
header h1 { margin: 0 0 4px; font-size: 28px; }
.meta { color: var(--muted); margin: 0 0 8px; }
h2 { margin: 40px 0 12px; padding-bottom: 6px; border-bottom: 1px solid var(--line);
     font-size: 22px; }
h3 { margin: 28px 0 8px; font-size: 17px; }
a { color: var(--accent); text-decoration: none; }
a:hover { text-decoration: underline; }
nav ol { margin: 4px 0; padding-left: 22px; columns: 2; }
figure { margin: 12px 0 20px; padding: 10px; border: 1px solid var(--line);
         border-radius: 6px; background: #fff; }
figure img { display: block; max-width: 100%; height: auto; margin: 0 auto; }
figcaption { color: var(--muted); font-size: 13px; margin-top: 6px; }
.graphs { display: grid; grid-template-columns: repeat(auto-fill, minmax(340px, 1fr));
          gap: 12px; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; margin: 8px 0 16px; font-size: 13.5px; }
th, td { padding: 4px 10px; border-bottom: 1px solid var(--line); text-align: right;
         white-space: nowrap; }
th { background: var(--band); font-weight: 600; }
th:first-child, td:first-child, td.text, th.text { text-align: left; }
tbody tr:nth-child(even) { background: #fbfcfd; }
td code, .key { color: var(--muted); font-size: 12px; }
.note { color: var(--muted); font-size: 13.5px; }
.warn { color: #9a6700; }
details { margin: 8px 0; }
summary { cursor: pointer; color: var(--accent); }
footer { margin-top: 48px; color: var(--muted); font-size: 13px;
         border-top: 1px solid var(--line); padding-top: 12px; }
"""


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"


def _img(name: str, data: bytes, alt: str, caption: str | None = None) -> str:
    src = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    cap = f"<figcaption>{caption}</figcaption>" if caption else ""
    return (f'<figure><img src="{src}" alt="{_e(alt)}" data-file="{FILES_DIR}/{_e(name)}">'
            f"{cap}</figure>")


def _table(head: list[str], rows: list[list[str]], text_cols: int = 1) -> str:
    """An HTML table; cells are already-escaped HTML; the first ``text_cols`` columns
    are left-aligned."""
    left = ' class="text"'

    def cells(tag: str, values: list[str]) -> str:
        return "".join(f"<{tag}{left if i < text_cols else ''}>{v}</{tag}>"
                       for i, v in enumerate(values))

    body = "".join(f"<tr>{cells('td', r)}</tr>" for r in rows)
    return (f'<div class="scroll"><table><thead><tr>{cells("th", head)}</tr></thead>'
            f"<tbody>{body}</tbody></table></div>")


def _metric_name(key: str) -> str:
    name = METRIC_NAMES.get(key)
    if name is None and key.startswith("ospa_"):
        suffix = {"_loc": " localisation", "_card": " cardinality"}
        base = key
        extra = ""
        for s, word in suffix.items():
            if key.endswith(s):
                base, extra = key[: -len(s)], word
        name = f"{_ospa_label(base)}{extra} (px)"
    return _e(name if name is not None else key)


#: columns of the summary tables per kind: (heading, metric key)
SUMMARY_COLUMNS = {
    "single": (("success AUC", "success_auc"), ("precision @ 20 px", "precision_at_20"),
               ("mean IoU", "mean_iou"), ("centre error (px)", "mean_centre_error")),
    "multi": (("MOTA", "mota"), ("IDF1", "idf1"), ("HOTA", "hota"),
              ("OSPA(50,1) px", "ospa_50_1"), ("|cardinality error|",
                                                "mean_abs_cardinality_error")),
    "unscored": (),
}
_KIND_TITLES = {"single": "Single-object runs", "multi": "Multi-target runs",
                "unscored": "Runs without ground truth"}


def _summary(groups: list[Group], stats: dict[tuple[str, str], dict[str, Stat]]) -> str:
    """One table per kind: a row per (sequence, model), its headline metrics."""
    out = []
    for kind, columns in SUMMARY_COLUMNS.items():
        gs = [g for g in groups if g.kind == kind]
        if not gs:
            continue
        rows = []
        for g in gs:
            st = stats[(g.sequence, g.label)]
            rows.append([_e(g.sequence), _e(g.label), str(len(g.runs))]
                        + [_fmt_stat(st[k]) if k in st else "–"
                           for k in ["run.frames"] + [k for _, k in columns] + ["fps"]])
        head = (["sequence", "model", "runs", "frames"] + [_e(h) for h, _ in columns]
                + ["frames/s"])
        out.append(f"<h3>{_KIND_TITLES[kind]}</h3>" + _table(head, rows, text_cols=2))
    return "".join(out)
