"""``pgm view RUN_DIR``: a self-contained page to step through a recorded run.

:func:`write_view` reads the record that ``pgm track ... --record`` wrote into
``RUN_DIR/record`` (:mod:`pgm.app.record`) and writes ``RUN_DIR/view.html``: one file, with
its script, style, data and frames inline (the thumbnails as JPEG data URIs, the run's
``annotated.mp4`` as an MP4 data URI up to ``max_video_mb``, else linked beside the page),
so it opens from ``file://`` with no server and no network.

The page shows, frame by frame:

* the image with a *layer* per thing recorded — each particle variable's particles (size
  and colour follow the weight: larger and yellower is heavier), each coupling's message
  particles (crosses), the PHD intensity (dots) with the extracted states (plus signs) and
  the tracks (rings with identities), a plate's replicas (dots coloured by identity), the
  measurements (dashed grey boxes), the part estimates (dashed boxes) and the reported
  targets (boxes with identities);
* the factor graph (drawn from ``model.json``, else from the graph the record saved) with
  the *active factors* highlighted;
* small charts: ESS/N per variable over the frames with the resampling events (red
  ticks), the VB fixed point of the frame (ELBO after each iteration), σ̂ over the frames,
  the expected and extracted target counts;
* the annotated video, kept at the current frame while paused.

**What "active" means.** One layer is *active* at a time (click its name, or a node of the
graph; the first coupling's messages by default, else the first variable). The active
factors are the factors that produced what that layer shows in the current frame: for a
variable's particles (or a set's intensity, or a plate's replicas) its prior on the run's
first frame, else its transition, then its likelihoods, the couplings whose messages are
fused into it, the interactions between replicas and the conjugate (VB) factors on it; for
a message, its coupling; for the VB charts, the conjugate factor. Those factors are drawn
with an orange outline and the layer's variables with an orange ring; the other layers are
dimmed on the image.

Controls: *previous*/*next* buttons, a slider, the left and right arrow keys (Home and End:
first and last), and a frame counter (``#frame-counter``) that reads the current frame
number.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
from pathlib import Path
from typing import Any

from pgm.core.errors import InputError

__all__ = ["write_view", "graph_svg", "add_parser", "COMMANDS", "VIEW_FILE"]

#: the page's file name in the run folder
VIEW_FILE = "view.html"
#: the largest annotated video embedded in the page (MB); a larger one is linked
MAX_VIDEO_MB = 64.0
_PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
            "#17becf", "#bcbd22", "#7f7f7f"]


# -------------------------------------------------------------------------------------
# the factor graph as an SVG whose nodes can be highlighted
# -------------------------------------------------------------------------------------
class _Node:
    """A variable, factor or plate of a graph rebuilt from ``meta.json`` (for drawing)."""

    def __init__(self, **kw: Any):
        self.__dict__.update(kw)


class _Skeleton:
    """The structure of a graph (names, roles, kinds, plates) from a record's
    ``meta.json``: what :func:`pgm.plotting.graph_drawing.layout` reads, for a run whose
    graph cannot be loaded (a factor type from the user's own module)."""

    def __init__(self, meta: dict[str, Any]):
        self.name = str(meta.get("model", "model"))
        self.variables = {n: _Node(name=n, role=v.get("role", "part"), dim=v.get("dim", 0))
                          for n, v in meta.get("variables", {}).items()}
        self.factors = {n: _Node(name=n, kind=f.get("kind", "prior"), type=f.get("type", ""),
                                 variables=tuple(f.get("variables", ())))
                        for n, f in meta.get("factors", {}).items()}
        self.plates = [_Node(name=p["name"], variables=tuple(p["variables"]),
                             size_label=p.get("size_label", "K"))
                       for p in meta.get("plates", [])]

    def factors_of(self, variable: str, kind: str | None = None) -> list[_Node]:
        return [f for f in self.factors.values()
                if variable in f.variables and (kind is None or f.kind == kind)]

    def factors_by_kind(self, kind: str) -> list[_Node]:
        return [f for f in self.factors.values() if f.kind == kind]


def _type_name(factor: Any) -> str:
    return getattr(factor, "type", None) or type(factor).__name__


def graph_svg(graph: Any) -> str:
    """An inline SVG of ``graph`` in the notation of :mod:`pgm.plotting.graph_drawing`
    (the same layout and colours): ``<g class="variable|factor" data-node=NAME>`` per
    node, so that a page can highlight nodes by name."""
    from pgm.plotting.graph_drawing import KIND_COLOURS, ROLE_COLOURS, layout, plate_outlines

    pos = layout(graph)
    outlines = plate_outlines(graph, pos)
    plates = [box for box, _ in outlines]
    xs = [p[0] for p in pos.values()] + [b[0] for b in plates] + [b[2] for b in plates]
    ys = [p[1] for p in pos.values()] + [b[1] for b in plates] + [b[3] for b in plates]
    x0, x1 = min(xs) - 2.2, max(xs) + 1.8
    y0, y1 = min(ys) - 1.0, max(ys) + 1.0
    u = 46.0  # pixels per layout unit

    def px(p) -> tuple[float, float]:
        return (float(p[0]) - x0) * u, (y1 - float(p[1])) * u

    esc = html.escape
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" id="graph-svg" '
           f'viewBox="0 0 {(x1 - x0) * u:.0f} {(y1 - y0) * u:.0f}" role="img" '
           f'aria-label="factor graph of {esc(graph.name)}">']
    for (a, b, c, d), p in outlines:
        (sx, sy), (ex, ey) = px((a, d)), px((c, b))
        out.append(f'<rect class="plate" x="{sx:.1f}" y="{sy:.1f}" width="{ex - sx:.1f}" '
                   f'height="{ey - sy:.1f}" rx="6"/>'
                   f'<text class="plate-label" x="{sx + 5:.1f}" y="{sy + 13:.1f}">'
                   f'{esc(p.name)}</text><text class="plate-size" x="{ex - 6:.1f}" '
                   f'y="{ey - 6:.1f}" text-anchor="end">{esc(p.size_label)}</text>')
    for f in graph.factors.values():
        fx, fy = px(pos[f.name])
        for v in f.variables:
            vx, vy = px(pos[v])
            out.append(f'<line class="edge" x1="{fx:.1f}" y1="{fy:.1f}" x2="{vx:.1f}" '
                       f'y2="{vy:.1f}"/>')
        z = pos.get(f"z:{f.name}")
        if f.kind == "likelihood" and z is not None:
            zx, zy = px(z)
            out.append(f'<line class="edge" x1="{fx:.1f}" y1="{fy:.1f}" x2="{zx:.1f}" '
                       f'y2="{zy:.1f}"/><circle class="observed" cx="{zx:.1f}" '
                       f'cy="{zy:.1f}" r="{0.3 * u:.1f}"/><text class="z" x="{zx:.1f}" '
                       f'y="{zy + 4:.1f}" text-anchor="middle">z</text>')
        if f.kind == "interaction":
            out.append(f'<line class="edge dashed" x1="{fx:.1f}" y1="{fy:.1f}" '
                       f'x2="{fx + 0.6 * u:.1f}" y2="{fy - 0.6 * u:.1f}"/>')
    s = 0.3 * u
    for f in graph.factors.values():
        fx, fy = px(pos[f.name])
        label = _type_name(f)
        if f.kind == "likelihood" and label.endswith("Likelihood") and label != "Likelihood":
            label = label[:-len("Likelihood")]
        colour = KIND_COLOURS.get(f.kind, "#999")
        # the label on the side away from its variable (so that it crosses no edge)
        lx, ly, anchor = fx, fy + s / 2 + 11, "middle"
        if len(f.variables) == 1:
            dx, dy = (float(a - b) for a, b in zip(pos[f.name], pos[f.variables[0]],
                                                    strict=True))
            if dx < -0.3:
                lx, ly, anchor = fx - s / 2 - 3, fy + 3, "end"
            elif dx > 0.3:
                lx, ly, anchor = fx + s / 2 + 3, fy + 3, "start"
            elif dy > 0.3:
                ly = fy - s / 2 - 4
        out.append(f'<g class="factor" data-node="{esc(f.name)}" data-kind="{esc(f.kind)}">'
                   f'<title>{esc(f.name)} ({esc(_type_name(f))}, {esc(f.kind)})</title>'
                   f'<rect class="halo" x="{fx - s:.1f}" y="{fy - s:.1f}" width="{2 * s:.1f}" '
                   f'height="{2 * s:.1f}" rx="4"/>'
                   f'<rect class="box" x="{fx - s / 2:.1f}" y="{fy - s / 2:.1f}" '
                   f'width="{s:.1f}" height="{s:.1f}" fill="{colour}"/>'
                   f'<text class="flabel" x="{lx:.1f}" y="{ly:.1f}" '
                   f'text-anchor="{anchor}">{esc(label)}</text></g>')
    r = 0.45 * u
    for v in graph.variables.values():
        vx, vy = px(pos[v.name])
        out.append(f'<g class="variable" data-node="{esc(v.name)}">'
                   f'<title>{esc(v.name)} ({esc(v.role)}, d={v.dim})</title>'
                   f'<circle class="halo" cx="{vx:.1f}" cy="{vy:.1f}" r="{r + 6:.1f}"/>'
                   f'<circle class="node" cx="{vx:.1f}" cy="{vy:.1f}" r="{r:.1f}" '
                   f'fill="{ROLE_COLOURS.get(v.role, "#ddd")}"/>'
                   f'<text class="vname" x="{vx:.1f}" y="{vy + 1:.1f}" text-anchor="middle">'
                   f'{esc(v.name)}</text><text class="vrole" x="{vx:.1f}" y="{vy + 12:.1f}" '
                   f'text-anchor="middle">{esc(v.role)}, d={v.dim}</text></g>')
    out.append("</svg>")
    return "".join(out)


def _load_graph(run: Path, meta: dict[str, Any]) -> Any:
    """The run's graph: ``model.json``, else the record's ``graph.json``, else the
    structure in ``meta.json``."""
    import pgm.models  # noqa: F401 - registers the toolkit's factor types for loading
    from pgm.core.graph import FactorGraph

    for p in (run / "model.json", run / "record" / "graph.json"):
        if p.is_file():
            try:
                return FactorGraph.load(p)
            except (ValueError, KeyError, TypeError, AttributeError, RecursionError):
                continue
    return _Skeleton(meta)


# -------------------------------------------------------------------------------------
# layers: what the page can draw, and the factors behind each
# -------------------------------------------------------------------------------------
def _factors_behind(graph: Any, variable: str) -> tuple[list[str], list[str]]:
    """Factors that shape ``variable``'s belief on the first frame and on later frames."""
    names = lambda fs: [f.name for f in fs]  # noqa: E731
    rest = (names(graph.factors_of(variable, "likelihood"))
            + names(graph.factors_of(variable, "coupling"))
            + names(graph.factors_of(variable, "interaction"))
            + names(graph.factors_of(variable, "conjugate")))
    return (names(graph.factors_of(variable, "prior")) + rest,
            names(graph.factors_of(variable, "transition")) + rest)


def _layers(graph: Any, meta: dict[str, Any], frames: list[dict[str, Any]]) -> list[dict]:
    layers: list[dict[str, Any]] = []
    colour = iter(_PALETTE * 4)
    seen_vars: dict[str, str] = {}
    for rec in frames:
        for key in ("variables", "sets", "replicas"):
            for v in rec.get(key, {}):
                seen_vars.setdefault(v, key)
    for v, key in seen_vars.items():
        first, later = _factors_behind(graph, v)
        kind = {"variables": "particles", "sets": "set", "replicas": "replicas"}[key]
        info = meta.get("variables", {}).get(v, {})
        label = {"particles": f"{v}: particles", "set": f"{v}: PHD intensity",
                 "replicas": f"{v}: replicas' particles"}[kind]
        layers.append({"id": f"{kind}:{v}", "kind": kind, "name": v, "label": label,
                       "colour": next(colour), "image": bool(info.get("image", True)),
                       "factors_first": first, "factors": later, "variables": [v]})
    seen_msgs: dict[tuple, None] = {}
    for rec in frames:
        for m in rec.get("messages", []):
            seen_msgs.setdefault((m.get("factor"), m["src"], m["dst"]), None)
    for f, src, dst in seen_msgs:
        info = meta.get("variables", {}).get(dst, {})
        layers.append({"id": f"message:{f}:{src}:{dst}", "kind": "message", "factor": f,
                       "src": src, "dst": dst,
                       "label": f"message {src} → {dst}" + (f" ({f})" if f else ""),
                       "colour": next(colour), "image": bool(info.get("image", True)),
                       "factors_first": [f] if f else [], "factors": [f] if f else [],
                       "variables": [src, dst]})
    conj = sorted({name for rec in frames for name in rec.get("vb", {})})
    for f in conj:
        fv = list(meta.get("factors", {}).get(f, {}).get("variables", []))
        layers.append({"id": f"vb:{f}", "kind": "vb", "name": f,
                       "label": f"VB fixed point ({f})", "colour": "#7b2cbf", "image": False,
                       "factors_first": [f], "factors": [f], "variables": fv})
    output = list(meta.get("output", []))
    if any(rec.get("measurements") for rec in frames):
        liks = [f.name for v in output for f in graph.factors_of(v, "likelihood")]
        layers.append({"id": "measurements", "kind": "measurements", "label": "measurements",
                       "colour": "#9e9e9e", "image": True, "factors_first": liks,
                       "factors": liks, "variables": output})
    if any(v.get("box") for v in meta.get("variables", {}).values()) and any(
            rec.get("variables") for rec in frames):
        layers.append({"id": "estimates", "kind": "estimates", "label": "part estimates",
                       "colour": "#00bcd4", "image": True, "factors_first": [],
                       "factors": [], "variables": output})
    layers.append({"id": "targets", "kind": "targets", "label": "reported targets",
                   "colour": "#ffffff", "image": True, "factors_first": [], "factors": [],
                   "variables": output})
    return layers


# -------------------------------------------------------------------------------------
# the page
# -------------------------------------------------------------------------------------
def _data_uri(path: Path, mime: str) -> str:
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _script_json(value: Any) -> str:
    """JSON that is safe inside a ``<script type="application/json">`` element."""
    text = json.dumps(value, separators=(",", ":"), allow_nan=False)
    return text.replace("</", "<\\/").replace("<!--", "<\\!--")


#: the fields of a ``record.jsonl`` line the page reads, and the JSON type of each
_FRAME_FIELDS: dict[str, type | tuple] = {
    "i": int, "t": int, "frame": int, "image": (str, type(None)), "variables": dict,
    "messages": list, "sets": dict, "vb": dict, "replicas": dict, "plate": dict,
    "measurements": list, "targets": dict, "dropped": bool}
_JSON_NAMES = {int: "an integer", str: "a string", dict: "an object", list: "a list",
               bool: "true or false", type(None): "null"}


def _image_path(folder: Path, name: str, where: str) -> Path:
    """The thumbnail a record line names, inside the record folder *by name*: relative,
    without ``..`` (a crafted record must not make the page embed the user's other
    files; a ``record/frames`` that is a symbolic link to a data folder still works, as
    the name is checked, not where it resolves)."""
    parts = Path(name).parts
    if not name or Path(name).is_absolute() or ".." in parts or "\\" in name:
        raise InputError(f"{where}: image {name!r} is not a path inside {folder} (the "
                         f"record names its thumbnails relative to it, e.g. "
                         f"frames/000001.jpg)")
    return folder / name


def _check_frames(folder: Path, frames: list[Any]) -> list[Path | None]:
    """Check every line of ``record.jsonl`` (an object; its fields of the JSON types the
    page reads; every number finite; a frame number >= 1; an image path inside the
    record) and return each line's thumbnail path (None: none recorded)."""
    images: list[Path | None] = []
    for k, rec in enumerate(frames):
        where = f"{folder / 'record.jsonl'} line {k + 1}"
        if not isinstance(rec, dict):
            raise InputError(f"{where} is not a JSON object but {type(rec).__name__}")
        for key, kind in _FRAME_FIELDS.items():
            if key not in rec:
                continue
            kinds = kind if isinstance(kind, tuple) else (kind,)
            value = rec[key]
            if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
                want = " or ".join(_JSON_NAMES[t] for t in kinds)
                raise InputError(f"{where}: {key!r} must be {want}, got {value!r:.40}")
        frame = rec.get("frame")
        if frame is None or frame < 1:
            raise InputError(f"{where}: 'frame' must be a frame number >= 1, got "
                             f"{frame!r:.40}")
        for m in rec.get("messages", []):
            if not (isinstance(m, dict) and isinstance(m.get("src"), str)
                    and isinstance(m.get("dst"), str)):
                raise InputError(f"{where}: every message must be an object with 'src' and "
                                 f"'dst' names, got {m!r:.60}")
        for key in ("variables", "sets", "replicas", "vb"):
            if not all(isinstance(v, (dict, list)) for v in rec.get(key, {}).values()):
                raise InputError(f"{where}: every entry of {key!r} must be an object")
        try:
            json.dumps(rec, allow_nan=False)
        except ValueError:
            raise InputError(f"{where} holds a NaN or infinite number") from None
        name = rec.get("image")
        images.append(None if not name else _image_path(folder, name, where))
    return images


def _check_meta(folder: Path, meta: dict[str, Any]) -> None:
    """The fields of ``meta.json`` the page reads, of their JSON types."""
    where = folder / "meta.json"
    for key, kind in (("variables", dict), ("factors", dict), ("output", list)):
        if key in meta and not isinstance(meta[key], kind):
            raise InputError(f"{where}: {key!r} must be {_JSON_NAMES[kind]}")
    for key in ("variables", "factors"):
        if not all(isinstance(v, dict) for v in meta.get(key, {}).values()):
            raise InputError(f"{where}: every entry of {key!r} must be an object")
    size = meta.get("image_size")
    if size is not None and not (isinstance(size, list) and len(size) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            and v > 0 for v in size)):
        raise InputError(f"{where}: 'image_size' must be two positive numbers")
    try:
        json.dumps(meta, allow_nan=False)
    except ValueError:
        raise InputError(f"{where} holds a NaN or infinite number") from None


def write_view(run_dir: str | Path, out: str | Path | None = None, *,
               max_video_mb: float = MAX_VIDEO_MB) -> Path:
    """Write the viewer page of a recorded run.

    Parameters
    ----------
    run_dir : str or Path
        A ``pgm track --record`` output folder (``record/`` inside it).
    out : str or Path, optional
        The page; default ``run_dir/view.html``.
    max_video_mb : float
        Embed ``annotated.mp4`` when it is at most this large; else the page links it by
        its name (it then plays while the page stays next to it). ``0``: never embed.

    Returns
    -------
    Path
        The page written.

    Raises
    ------
    InputError
        ``run_dir`` holds no record, or a record that ``run.json`` says belongs to another
        run (a later run without ``--record`` in the same folder); a ``record.jsonl`` line
        that is not an object, has a field of the wrong type or a non-finite number, or
        names an image outside ``record/`` (absolute, or with ``..``): named by its line.
    """
    from pgm.app.record import RECORD_DIR, read_record
    from pgm.io.outputs import prepare_output_file

    run = Path(run_dir)
    if not run.is_dir():
        raise InputError(f"{run} is not a folder (give the --out folder of a recorded run)")
    try:
        meta, frames = read_record(run / RECORD_DIR)
    except RecursionError:
        raise InputError(f"{run / RECORD_DIR}: meta.json or record.jsonl holds JSON nested "
                         f"too deeply") from None
    run_info: dict[str, Any] = {}
    run_json = run / "run.json"
    if run_json.is_file():
        try:
            run_info = json.loads(run_json.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError):
            run_info = {}
        rec = run_info.get("record") if isinstance(run_info, dict) else None
        if not isinstance(rec, dict) or rec.get("id") != meta.get("id"):
            raise InputError(f"{run / RECORD_DIR} was recorded by an earlier run, not by the "
                             f"run in {run_json}; re-run 'pgm track ... --record'")
    if not frames:
        raise InputError(f"{run / RECORD_DIR} holds no recorded frame")
    _check_meta(run / RECORD_DIR, meta)
    thumbs = _check_frames(run / RECORD_DIR, frames)
    graph = _load_graph(run, meta)
    images = [_data_uri(p, "image/jpeg") if p is not None and p.is_file() else None
              for p in thumbs]
    video: dict[str, Any] | None = None
    mp4 = run / "annotated.mp4"
    if mp4.is_file() and mp4.stat().st_size > 0:
        size_mb = mp4.stat().st_size / 1e6
        embed = size_mb <= max_video_mb
        video = {"src": _data_uri(mp4, "video/mp4") if embed else mp4.name,
                 "embedded": embed, "codec": run_info.get("video_codec"),
                 "size_mb": round(size_mb, 2)}
    layers = _layers(graph, meta, frames)
    data = {"meta": meta, "frames": frames, "layers": layers,
            "run": {k: run_info.get(k) for k in ("model", "source", "complete", "stopped",
                                                 "frames", "fps", "video_codec")
                    if k in run_info},
            "video": None if video is None else {k: v for k, v in video.items() if k != "src"}}
    title = f"pgm view — {meta.get('model', '')} — {run.resolve().name}"
    parts = {"TITLE": html.escape(title), "CSS": _CSS, "GRAPH": graph_svg(graph),
             "VIDEO": "" if video is None else
             f'<video id="video" controls muted playsinline preload="auto" '
             f'src="{html.escape(video["src"])}"></video>',
             "DATA": _script_json(data), "IMAGES": _script_json(images), "JS": _JS}
    # one pass over the template: text substituted in is never searched again
    page = re.sub(r"__(TITLE|CSS|GRAPH|VIDEO|DATA|IMAGES|JS)__", lambda m: parts[m.group(1)],
                  _TEMPLATE)
    target = prepare_output_file(Path(out) if out is not None else run / "view.html",
                                 "the viewer page")
    tmp = target.with_name(f".{target.name}.tmp")
    try:
        tmp.write_text(page, encoding="utf-8")
        tmp.replace(target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(f"cannot write {target}: {exc.strerror or exc}") from None
    return target


# -------------------------------------------------------------------------------------
# command line
# -------------------------------------------------------------------------------------
def _non_negative_mb(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not math.isfinite(v) or v < 0:
        raise InputError(f"--max-video-mb must be a number >= 0, got {text!r}")
    return v


def add_parser(subparsers) -> None:
    """Add ``pgm view`` to the ``pgm`` sub-command parsers."""
    from pgm.app.cli import _path

    v = subparsers.add_parser(
        "view", help="write RUN_DIR/view.html: step through a recorded run in a browser",
        description="Write a self-contained page (RUN_DIR/view.html) to step through a run "
                    "recorded with 'pgm track ... --record': particles, messages, the PHD "
                    "intensity, the VB fixed point, ESS and resampling, beside the factor "
                    "graph. Example: pgm track seq --gt gt.txt --out run --record && "
                    "pgm view run")
    v.add_argument("run_dir", type=_path("RUN_DIR"), metavar="RUN_DIR",
                   help="output folder of 'pgm track --record'")
    v.add_argument("--out", type=_path("--out"), default=None, metavar="FILE.html",
                   help="where to write the page (default: RUN_DIR/view.html)")
    v.add_argument("--max-video-mb", type=_non_negative_mb, default=MAX_VIDEO_MB,
                   help=f"embed annotated.mp4 up to this size, else link it "
                        f"(default: {MAX_VIDEO_MB:g})")


def cmd_view(args) -> int:
    """``pgm view``: write the page and print where it is."""
    path = write_view(args.run_dir, args.out, max_video_mb=args.max_video_mb)
    print(f"wrote {path} (open it in a browser)")
    return 0


#: sub-commands of this module (``pgm.app.cli.EXTENSIONS``)
COMMANDS = {"view": cmd_view}


_CSS = r"""
* { box-sizing: border-box; }
body { margin: 0; font: 13px/1.35 system-ui, -apple-system, "Segoe UI", sans-serif;
       background: #15171c; color: #e8e8e8; }
header { display: flex; flex-wrap: wrap; align-items: center; gap: 10px;
         padding: 8px 12px; background: #20232b; border-bottom: 1px solid #333; }
header h1 { font-size: 15px; margin: 0 12px 0 0; font-weight: 600; }
button { background: #2f3440; color: #eee; border: 1px solid #555; border-radius: 4px;
         padding: 3px 10px; cursor: pointer; font-size: 13px; }
button:hover { background: #3b4150; }
#slider { width: 280px; }
#counter { font-variant-numeric: tabular-nums; }
#frame-counter { font-weight: 700; font-size: 15px; color: #ffd54f; }
main { display: flex; gap: 12px; padding: 10px 12px; align-items: flex-start; flex-wrap: wrap; }
#left { flex: 1 1 560px; min-width: 320px; }
#right { flex: 0 1 460px; min-width: 300px; display: flex; flex-direction: column; gap: 8px; }
#stage { position: relative; background: #000; border: 1px solid #333; }
#canvas { display: block; width: 100%; height: auto; }
#latent { display: none; background: #fff; border: 1px solid #333; margin-top: 6px; }
.panel { background: #1d2027; border: 1px solid #333; border-radius: 6px; padding: 6px 8px; }
.panel h2 { font-size: 12px; margin: 0 0 4px; color: #aab; font-weight: 600;
            text-transform: uppercase; letter-spacing: .04em; }
#graph-svg { width: 100%; height: auto; background: #fafafa; border-radius: 4px; }
#graph-svg .edge { stroke: #444; stroke-width: 1.2; }
#graph-svg .edge.dashed { stroke: #2a9d8f; stroke-dasharray: 4 3; }
#graph-svg .plate { fill: none; stroke: #333; stroke-width: 1.4; }
#graph-svg .plate-label { font-size: 9px; fill: #333; }
#graph-svg .plate-size { font-size: 13px; font-style: italic; fill: #333; }
#graph-svg .observed { fill: #adb5bd; stroke: #000; }
#graph-svg .z { font-size: 10px; fill: #000; }
#graph-svg .box { stroke: #000; stroke-width: 1; }
#graph-svg .flabel { font-size: 8px; fill: #222; }
#graph-svg .vname { font-size: 10px; font-weight: 700; fill: #000; }
#graph-svg .vrole { font-size: 7px; fill: #222; }
#graph-svg .node { stroke: #000; stroke-width: 1.5; }
#graph-svg .halo { fill: none; stroke: none; }
#graph-svg g { cursor: pointer; }
#graph-svg g.active .halo { fill: rgba(255, 152, 0, .25); stroke: #ff9800; stroke-width: 3; }
#graph-svg g.factor.active .box { stroke: #ff9800; stroke-width: 3; }
#graph-svg g.variable.active .node { stroke: #ff9800; stroke-width: 4; }
#layers { list-style: none; margin: 0; padding: 0; }
#layers li { display: flex; align-items: center; gap: 6px; padding: 1px 3px; border-radius: 3px;
             cursor: pointer; }
#layers li.active { background: #3a3320; outline: 1px solid #ff9800; }
#layers .swatch { width: 12px; height: 12px; border-radius: 2px; border: 1px solid #888;
                  flex: none; }
#info { white-space: pre-wrap; font-family: ui-monospace, Menlo, Consolas, monospace;
        font-size: 12px; color: #ddd; min-height: 3.5em; }
.chart { width: 100%; height: 120px; display: block; background: #fff; border-radius: 4px; }
.chart text { font-size: 9px; fill: #333; }
#video { width: 100%; margin-top: 8px; background: #000; }
.muted { color: #99a; font-size: 11px; }
.legend span { margin-right: 10px; }
"""

_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<style>__CSS__</style>
</head>
<body>
<header>
  <h1 id="title"></h1>
  <button id="prev" title="previous frame (left arrow)">&#9664; previous</button>
  <input id="slider" type="range" min="0" max="0" value="0" step="1" aria-label="frame">
  <button id="next" title="next frame (right arrow)">next &#9654;</button>
  <span id="counter">frame <span id="frame-counter">-</span>
    <span class="muted">(<span id="position">-</span>)</span></span>
  <label title="zoom the image on the active layer"><input id="zoom" type="checkbox"> zoom
    to the active layer</label>
  <span id="status" class="muted"></span>
</header>
<main>
  <section id="left">
    <div id="stage"><canvas id="canvas" width="640" height="480"></canvas></div>
    <canvas id="latent" width="300" height="200"></canvas>
    <p class="muted legend">Particles: size and colour follow the weight (small dark blue
      light, large yellow heavy); crosses: message particles; plus signs: extracted PHD
      states; rings: PHD tracks; dashed grey: measurements; boxes: reported targets.
      Click a layer or a graph node to make it active.</p>
    __VIDEO__
  </section>
  <section id="right">
    <div class="panel"><h2>Factor graph &middot; active factors in orange</h2>__GRAPH__</div>
    <div class="panel"><h2>Layers</h2><ul id="layers"></ul></div>
    <div class="panel"><h2>This frame</h2><div id="info"></div></div>
    <div class="panel" id="panel-ess"><h2>ESS / N and resampling (red)</h2>
      <svg id="chart-ess" class="chart"></svg></div>
    <div class="panel" id="panel-elbo"><h2>VB fixed point: ELBO per iteration</h2>
      <svg id="chart-elbo" class="chart"></svg></div>
    <div class="panel" id="panel-sigma"><h2>VB noise &sigma;&#770; per frame</h2>
      <svg id="chart-sigma" class="chart"></svg></div>
    <div class="panel" id="panel-count"><h2>Targets: expected (PHD mass), extracted,
      reported</h2><svg id="chart-count" class="chart"></svg></div>
  </section>
</main>
<script type="application/json" id="pgm-data">__DATA__</script>
<script type="application/json" id="pgm-images">__IMAGES__</script>
<script>__JS__</script>
</body>
</html>
"""

_JS = r"""
"use strict";
(function () {
  const DATA = JSON.parse(document.getElementById("pgm-data").textContent);
  const IMAGES = JSON.parse(document.getElementById("pgm-images").textContent);
  const meta = DATA.meta, frames = DATA.frames, layers = DATA.layers;
  const W = (meta.image_size || [640, 480])[0], H = (meta.image_size || [640, 480])[1];
  // drawn at about 900 px whatever the frame size: thumbnails stretch, overlays stay crisp
  const scale = Math.min(3, 900 / Math.max(W, H));
  const canvas = document.getElementById("canvas"), ctx = canvas.getContext("2d");
  canvas.width = Math.round(W * scale); canvas.height = Math.round(H * scale);
  // image coordinates -> canvas: (x - x0) * k; the whole frame, or zoomed on a layer
  let view = {x0: 0, y0: 0, k: scale};
  const X = x => (x - view.x0) * view.k, Y = y => (y - view.y0) * view.k;
  const zoomBox = document.getElementById("zoom");
  const slider = document.getElementById("slider");
  slider.max = String(frames.length - 1);
  const NS = "http://www.w3.org/2000/svg";
  const PALETTE = ["#e6194b", "#3cb44b", "#ffe119", "#4363d8", "#f58231", "#911eb4",
                   "#46f0f0", "#f032e6", "#bcf60c", "#fabebe", "#008080", "#e6beff"];
  const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  const visible = {};
  layers.forEach(l => { visible[l.id] = true; });
  let active = (layers.find(l => l.kind === "message") ||
                layers.find(l => ["particles", "set", "replicas"].includes(l.kind)) ||
                layers[0] || {}).id;
  let current = 0;
  const cache = {};

  document.getElementById("title").textContent =
    (meta.model || "model") + " \u00b7 " + frames.length + " recorded frames";
  if (DATA.run && DATA.run.complete === false)
    document.getElementById("status").textContent =
      "run not complete: " + (DATA.run.stopped || "");

  function viridis(t) {
    t = Math.max(0, Math.min(1, t)) * (VIRIDIS.length - 1);
    const i = Math.min(VIRIDIS.length - 2, Math.floor(t)), f = t - i;
    const c = VIRIDIS[i].map((v, k) => Math.round(v + f * (VIRIDIS[i + 1][k] - v)));
    return "rgb(" + c.join(",") + ")";
  }
  function idColour(id) { return PALETTE[Math.abs(id) % PALETTE.length]; }
  function fmt(v, d) { return (v === null || v === undefined) ? "n/a" :
                        Number(v).toFixed(d === undefined ? 2 : d); }
  function layerById(id) { return layers.find(l => l.id === id); }

  // -- drawing on the image ------------------------------------------------------------
  function cloud(x, w, colour, alpha, opts) {
    if (!x || !x.length) return;
    const wmax = Math.max.apply(null, w.map(v => v || 0)) || 1;
    const order = w.map((v, i) => i).sort((a, b) => (w[a] || 0) - (w[b] || 0));
    for (const i of order) {
      if (x[i][0] === null || x[i][1] === null) continue;
      const t = Math.sqrt((w[i] || 0) / wmax), px = X(x[i][0]), py = Y(x[i][1]);
      const r = 1.5 + 5 * t;
      ctx.globalAlpha = alpha * (0.45 + 0.55 * t);
      if (opts && opts.cross) {
        ctx.strokeStyle = colour; ctx.lineWidth = 1.5;
        ctx.beginPath(); ctx.moveTo(px - r, py - r); ctx.lineTo(px + r, py + r);
        ctx.moveTo(px - r, py + r); ctx.lineTo(px + r, py - r); ctx.stroke();
      } else {
        ctx.fillStyle = (opts && opts.fill) || viridis(t);
        ctx.strokeStyle = colour; ctx.lineWidth = 1;
        ctx.beginPath(); ctx.arc(px, py, r, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
      }
    }
    ctx.globalAlpha = 1;
  }
  function box(b, colour, alpha, dashed, label) {
    if (!b || b.some(v => v === null)) return;
    ctx.globalAlpha = alpha; ctx.strokeStyle = colour; ctx.lineWidth = dashed ? 1 : 2;
    ctx.setLineDash(dashed ? [4, 3] : []);
    ctx.strokeRect(X(b[0]), Y(b[1]), b[2] * view.k, b[3] * view.k);
    ctx.setLineDash([]);
    if (label) {
      ctx.fillStyle = colour; ctx.font = "bold 12px sans-serif";
      ctx.fillText(label, X(b[0]) + 2, Math.max(11, Y(b[1]) - 3));
    }
    ctx.globalAlpha = 1;
  }
  function plus(x, y, colour, size) {
    ctx.strokeStyle = "#fff"; ctx.lineWidth = 4;
    ctx.beginPath(); ctx.moveTo(x - size, y); ctx.lineTo(x + size, y);
    ctx.moveTo(x, y - size); ctx.lineTo(x, y + size); ctx.stroke();
    ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.stroke();
  }
  function partBox(est, v) {
    const info = meta.variables[v] || {};
    if (!info.box || !est) return null;
    const c = info.box.map(k => est[k]);
    return [c[0] - c[2] / 2, c[1] - c[3] / 2, c[2], c[3]];
  }
  function drawLayer(l, rec, alpha) {
    if (l.kind === "particles") {
      const d = (rec.variables || {})[l.name];
      if (d && l.image) cloud(d.x, d.w, l.colour, alpha);
    } else if (l.kind === "message") {
      const m = (rec.messages || []).find(m => m.src === l.src && m.dst === l.dst &&
                                               (m.factor || null) === (l.factor || null));
      if (m && l.image) cloud(m.x, m.w, l.colour, alpha, {cross: true});
    } else if (l.kind === "set") {
      const s = (rec.sets || {})[l.name];
      if (!s) return;
      cloud(s.x, s.w, l.colour, alpha);
      ctx.globalAlpha = alpha;
      for (const e of s.extracted || []) plus(X(e[0]), Y(e[1]), l.colour, 7);
      for (const t of s.tracks || []) {
        if (t.x === null || t.y === null) continue;
        ctx.strokeStyle = idColour(t.id); ctx.lineWidth = 2;
        ctx.setLineDash(t.coasting ? [3, 3] : []);
        ctx.beginPath(); ctx.arc(X(t.x), Y(t.y), 11, 0, 2 * Math.PI); ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = idColour(t.id); ctx.font = "bold 11px sans-serif";
        ctx.fillText(String(t.id), X(t.x) + 12, Y(t.y) - 8);
      }
      ctx.globalAlpha = 1;
    } else if (l.kind === "replicas") {
      for (const r of (rec.replicas || {})[l.name] || []) {
        const c = r.id ? idColour(r.id) : "#bbbbbb";
        if (l.image) cloud(r.x, r.w, c, alpha);
      }
    } else if (l.kind === "measurements") {
      for (const m of rec.measurements || []) box(m, "#c8c8c8", alpha, true);
    } else if (l.kind === "estimates") {
      for (const [v, d] of Object.entries(rec.variables || {})) {
        const lv = layerById("particles:" + v);
        box(partBox(d.estimate, v), lv ? lv.colour : l.colour, alpha, true);
      }
    } else if (l.kind === "targets") {
      const t = rec.targets;
      if (!t) return;
      t.boxes.forEach((b, i) => box(b, idColour(t.ids[i]), alpha, false, String(t.ids[i])));
    }
  }
  function layerPoints(l, rec) {
    if (!l || !l.image) return [];
    if (l.kind === "particles") return ((rec.variables || {})[l.name] || {}).x || [];
    if (l.kind === "set") return ((rec.sets || {})[l.name] || {}).x || [];
    if (l.kind === "message") {
      const m = (rec.messages || []).find(m => m.src === l.src && m.dst === l.dst);
      return m ? m.x : [];
    }
    if (l.kind === "replicas")
      return [].concat(...((rec.replicas || {})[l.name] || []).map(r => r.x));
    const t = rec.targets;
    return t ? [].concat(...t.boxes.map(b => [[b[0], b[1]], [b[0] + b[2], b[1] + b[3]]])) : [];
  }
  function zoomed(rec) {
    // around the active layer's points and the reported targets (else every layer's
    // points), with the frame's aspect ratio
    let pts = layerPoints(layerById(active), rec).filter(p => p[0] !== null && p[1] !== null);
    if (pts.length) pts = pts.concat(layerPoints(layerById("targets"), rec));
    else for (const l of layers) pts = pts.concat(layerPoints(l, rec));
    pts = pts.filter(p => p[0] !== null && p[1] !== null);
    if (!pts.length) return {x0: 0, y0: 0, k: scale};
    const xs = pts.map(p => p[0]), ys = pts.map(p => p[1]);
    const cx = (Math.min(...xs) + Math.max(...xs)) / 2, cy = (Math.min(...ys) + Math.max(...ys)) / 2;
    let vw = Math.max(1.6 * (Math.max(...xs) - Math.min(...xs)), 40, W / 8);
    let vh = Math.max(1.6 * (Math.max(...ys) - Math.min(...ys)), 40 * H / W, H / 8);
    if (vw / vh > W / H) vh = vw * H / W; else vw = vh * W / H;
    vw = Math.min(vw, W); vh = Math.min(vh, H);
    const x0 = Math.max(0, Math.min(W - vw, cx - vw / 2));
    const y0 = Math.max(0, Math.min(H - vh, cy - vh / 2));
    return {x0: x0, y0: y0, k: canvas.width / vw};
  }
  function drawLatent(rec) {
    const lat = document.getElementById("latent");
    const l = layerById(active);
    if (!l || l.image !== false || !["particles", "replicas"].includes(l.kind)) {
      lat.style.display = "none"; return;
    }
    let pts = [], ws = [];
    if (l.kind === "particles" && rec.variables && rec.variables[l.name]) {
      pts = rec.variables[l.name].x; ws = rec.variables[l.name].w;
    } else if (l.kind === "replicas") {
      for (const r of (rec.replicas || {})[l.name] || []) { pts = pts.concat(r.x); ws = ws.concat(r.w); }
    }
    lat.style.display = "block";
    const c = lat.getContext("2d");
    c.clearRect(0, 0, lat.width, lat.height);
    c.fillStyle = "#333"; c.font = "11px sans-serif";
    c.fillText(l.name + " (not an image position: its first two state columns)", 6, 13);
    if (!pts.length) return;
    const xs = pts.map(p => p[0]), ys = pts.map(p => p[1]);
    const x0 = Math.min(...xs), x1 = Math.max(...xs) + 1e-9, y0 = Math.min(...ys),
          y1 = Math.max(...ys) + 1e-9, wmax = Math.max(...ws) || 1;
    pts.forEach((p, i) => {
      const t = Math.sqrt((ws[i] || 0) / wmax);
      c.fillStyle = viridis(t);
      c.beginPath();
      c.arc(10 + (p[0] - x0) / (x1 - x0) * (lat.width - 20),
            lat.height - 10 - (p[1] - y0) / (y1 - y0) * (lat.height - 30), 1.5 + 4 * t, 0,
            2 * Math.PI);
      c.fill();
    });
  }

  // -- the factor graph ----------------------------------------------------------------
  function highlight(rec) {
    const l = layerById(active);
    const names = new Set();
    if (l) {
      (rec.t === 0 ? l.factors_first : l.factors).forEach(n => names.add(n));
      (l.variables || []).forEach(n => names.add(n));
    }
    document.querySelectorAll("#graph-svg g[data-node]").forEach(g => {
      g.classList.toggle("active", names.has(g.getAttribute("data-node")));
    });
  }
  document.querySelectorAll("#graph-svg g[data-node]").forEach(g => {
    g.addEventListener("click", () => {
      const name = g.getAttribute("data-node");
      const isFactor = g.classList.contains("factor");
      const pick = isFactor ?
        (layers.find(l => l.kind === "message" && l.factor === name) ||
         layers.find(l => l.kind === "vb" && l.name === name) ||
         layers.find(l => (l.factors || []).includes(name) ||
                          (l.factors_first || []).includes(name))) :
        (layers.find(l => ["particles", "set", "replicas"].includes(l.kind) && l.name === name) ||
         layers.find(l => (l.variables || []).includes(name)));
      if (pick) setActive(pick.id);
    });
  });

  // -- layers list and info --------------------------------------------------------------
  const list = document.getElementById("layers");
  for (const l of layers) {
    const li = document.createElement("li");
    li.dataset.layer = l.id;
    const cb = document.createElement("input");
    cb.type = "checkbox"; cb.checked = true; cb.title = "show on the image";
    cb.addEventListener("click", ev => { ev.stopPropagation(); visible[l.id] = cb.checked;
                                          render(); });
    const sw = document.createElement("span");
    sw.className = "swatch"; sw.style.background = l.colour;
    const tx = document.createElement("span");
    tx.textContent = l.label;
    li.append(cb, sw, tx);
    li.addEventListener("click", () => setActive(l.id));
    list.appendChild(li);
  }
  function setActive(id) { active = id; render(); }

  function infoText(l, rec) {
    if (!l) return "";
    const out = [l.label];
    const facs = rec.t === 0 ? l.factors_first : l.factors;
    if (facs && facs.length) out.push("active factors: " + facs.join(", "));
    const N = (meta.num_particles || {})[l.name];
    if (l.kind === "particles") {
      const d = (rec.variables || {})[l.name];
      if (d) {
        out.push(d.n + " particles" + (N && d.n !== N ? " (" + N + " own + message particles)" : "")
                 + ", " + d.x.length + " shown holding " + fmt(100 * (d.shown_mass || 0), 1)
                 + "% of the weight");
        out.push("ESS " + fmt(d.ess, 1) + (N ? " of " + N : "") +
                 (d.resampled ? ", resampled" : ", not resampled"));
        if (d.own_mass !== null && d.own_mass !== undefined)
          out.push("own mass after fusion " + fmt(d.own_mass, 3));
        if (d.log_evidence !== null && d.log_evidence !== undefined)
          out.push("log evidence increment " + fmt(d.log_evidence, 3));
        if (d.estimate) out.push("estimate [" + d.estimate.map(v => fmt(v, 1)).join(", ") + "]");
      }
    } else if (l.kind === "message") {
      const m = (rec.messages || []).find(m => m.src === l.src && m.dst === l.dst);
      if (m) out.push(m.n + " message particles, " + m.x.length + " shown");
    } else if (l.kind === "set") {
      const s = (rec.sets || {})[l.name];
      if (s) {
        out.push("expected number of targets " + fmt(s.mass, 2) + ", " + s.n + " particles ("
                 + s.x.length + " shown)" + (s.resampled_to ? ", resampled to " + s.resampled_to : ""));
        out.push((s.extracted || []).length + " extracted, " + (s.tracks || []).length + " tracks");
      }
    } else if (l.kind === "replicas") {
      const rs = (rec.replicas || {})[l.name] || [];
      out.push(rs.length + " replicas");
      for (const r of rs)
        out.push("  id " + (r.id || "-") + (r.reported ? "" : " (not reported)") + ": ESS " +
                 fmt(r.ess, 1) + (r.resampled ? ", resampled" : "") + ", existence " +
                 fmt(r.existence, 2));
      if (rec.plate) out.push("births " + rec.plate.births + ", deaths " +
                              (rec.plate.deaths.join(", ") || "none"));
    } else if (l.kind === "vb") {
      const v = (rec.vb || {})[l.name];
      if (v) {
        out.push(v.iterations + " iterations; ELBO " + v.elbo.map(e => fmt(e, 2)).join(" \u2192 "));
        out.push("\u03c3\u0302 = " + v.sigma.map(s => fmt(s, 3)).join(", ") +
                 "  (noise: " + v.noise + ")");
      } else out.push("no VB update this frame");
    } else if (l.kind === "targets" && rec.targets) {
      out.push(rec.targets.ids.length + " reported " + (rec.targets.text || ""));
    } else if (l.kind === "measurements") {
      out.push((rec.measurements || []).length + " measurements");
    }
    if (rec.dropped) out.push("this frame was withheld from the tracker (predicted through)");
    return out.join("\n");
  }

  // -- charts --------------------------------------------------------------------------
  function el(tag, attrs, parent) {
    const e = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    if (parent) parent.appendChild(e);
    return e;
  }
  function chart(id, series, opts) {
    const svg = document.getElementById(id);
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    const w = svg.clientWidth || 420, h = svg.clientHeight || 120;
    svg.setAttribute("viewBox", "0 0 " + w + " " + h);
    const pts = [].concat(...series.map(s => s.points)).filter(p => p[1] !== null);
    if (!pts.length) { el("text", {x: 8, y: 16}, svg).textContent = opts.empty || "no data"; return; }
    let x0 = Math.min(...pts.map(p => p[0])), x1 = Math.max(...pts.map(p => p[0]));
    let y0 = opts.y0 !== undefined ? opts.y0 : Math.min(...pts.map(p => p[1]));
    let y1 = opts.y1 !== undefined ? opts.y1 : Math.max(...pts.map(p => p[1]));
    if (x1 === x0) { x0 -= 1; x1 += 1; }
    if (y1 === y0) { y0 -= 1; y1 += 1; }
    const L = 44, R = 8, T = 8, B = 18;
    const sx = x => L + (x - x0) / (x1 - x0) * (w - L - R);
    const sy = y => h - B - (y - y0) / (y1 - y0) * (h - T - B);
    el("line", {x1: L, y1: h - B, x2: w - R, y2: h - B, stroke: "#999"}, svg);
    el("line", {x1: L, y1: T, x2: L, y2: h - B, stroke: "#999"}, svg);
    el("text", {x: L - 3, y: T + 8, "text-anchor": "end"}, svg).textContent = fmt(y1, opts.yd);
    el("text", {x: L - 3, y: h - B, "text-anchor": "end"}, svg).textContent = fmt(y0, opts.yd);
    el("text", {x: L, y: h - 5}, svg).textContent = (opts.xlabel || "") + " " + fmt(x0, 0);
    el("text", {x: w - R, y: h - 5, "text-anchor": "end"}, svg).textContent = fmt(x1, 0);
    if (opts.vline !== undefined)
      el("line", {x1: sx(opts.vline), y1: T, x2: sx(opts.vline), y2: h - B, stroke: "#ff9800",
                  "stroke-width": 2}, svg);
    let ly = T + 9;
    for (const s of series) {
      const p = s.points.filter(q => q[1] !== null);
      if (!p.length) continue;
      el("polyline", {points: p.map(q => sx(q[0]).toFixed(1) + "," + sy(q[1]).toFixed(1)).join(" "),
                      fill: "none", stroke: s.colour, "stroke-width": 1.6}, svg);
      if (s.dots)
        for (const q of p) el("circle", {cx: sx(q[0]), cy: sy(q[1]), r: 2.5, fill: s.colour}, svg);
      const t = el("text", {x: w - R - 2, y: ly, "text-anchor": "end", fill: s.colour}, svg);
      t.textContent = s.name; ly += 10;
    }
    for (const m of opts.marks || [])
      el("path", {d: "M" + sx(m[0]) + "," + (h - B) + " l-3,6 l6,0 z", fill: "#e53935"}, svg);
  }
  function drawCharts(rec) {
    const fx = frames.map(f => f.frame);
    const ess = [], marks = [];
    for (const l of layers) {
      if (l.kind !== "particles" && l.kind !== "replicas") continue;
      const N = (meta.num_particles || {})[l.name] || 1;
      const pts = frames.map(f => {
        if (l.kind === "particles") {
          const d = (f.variables || {})[l.name];
          if (d && d.resampled) marks.push([f.frame]);
          return [f.frame, d && d.ess !== null ? d.ess / N : null];
        }
        const rs = ((f.replicas || {})[l.name] || []).filter(r => r.ess !== null);
        if (rs.some(r => r.resampled)) marks.push([f.frame]);
        return [f.frame, rs.length ? rs.reduce((a, r) => a + r.ess, 0) / rs.length / N : null];
      });
      ess.push({name: l.name + (l.kind === "replicas" ? " (mean over replicas)" : ""),
                colour: l.colour, points: pts});
    }
    document.getElementById("panel-ess").style.display = ess.length ? "" : "none";
    if (ess.length) chart("chart-ess", ess, {y0: 0, y1: 1, vline: rec.frame, marks: marks,
                                             xlabel: "frame", yd: 1});
    const vbNames = layers.filter(l => l.kind === "vb").map(l => l.name);
    document.getElementById("panel-elbo").style.display = vbNames.length ? "" : "none";
    document.getElementById("panel-sigma").style.display = vbNames.length ? "" : "none";
    if (vbNames.length) {
      chart("chart-elbo", vbNames.map((n, k) => ({
        name: n, colour: ["#7b2cbf", "#1f77b4", "#d62728"][k % 3], dots: true,
        points: (((rec.vb || {})[n] || {}).elbo || []).map((e, i) => [i + 1, e])})),
        {xlabel: "iteration", empty: "no VB update in this frame"});
      const sig = [];
      vbNames.forEach(n => {
        const dims = Math.max(0, ...frames.map(f => (((f.vb || {})[n] || {}).sigma || []).length));
        for (let k = 0; k < dims; k++)
          sig.push({name: "\u03c3\u0302" + (dims > 1 ? "[" + k + "]" : ""),
                    colour: ["#7b2cbf", "#e377c2", "#17becf"][k % 3],
                    points: frames.map(f => [f.frame,
                                             (((f.vb || {})[n] || {}).sigma || [])[k] ?? null])});
      });
      chart("chart-sigma", sig, {vline: rec.frame, xlabel: "frame"});
    }
    const sets = layers.filter(l => l.kind === "set");
    const hasTargets = frames.some(f => f.targets);
    const multi = sets.length || frames.some(f => f.replicas);
    document.getElementById("panel-count").style.display = multi ? "" : "none";
    if (multi) {
      const ser = [];
      for (const l of sets) {
        ser.push({name: "expected", colour: "#d62728",
                  points: frames.map(f => [f.frame, ((f.sets || {})[l.name] || {}).mass ?? null])});
        ser.push({name: "extracted", colour: "#2ca02c",
                  points: frames.map(f => [f.frame,
                                           (((f.sets || {})[l.name] || {}).extracted || []).length])});
      }
      if (hasTargets) ser.push({name: "reported", colour: "#1f77b4",
                                points: frames.map(f => [f.frame,
                                                         f.targets ? f.targets.ids.length : null])});
      chart("chart-count", ser, {y0: 0, vline: rec.frame, xlabel: "frame", yd: 1});
    }
    void fx;
  }

  // -- the video -----------------------------------------------------------------------
  const video = document.getElementById("video");
  const fps = meta.fps || 25;
  function syncVideo(rec) {
    if (!video || !video.paused || video.readyState < 1) return;
    const t = (rec.t + 0.5) / fps;
    if (Math.abs(video.currentTime - t) > 0.5 / fps) {
      try { video.currentTime = Math.min(t, (video.duration || t)); } catch (e) { /* not seekable */ }
    }
  }
  if (video) video.addEventListener("loadedmetadata", () => syncVideo(frames[current]));

  // -- one frame ------------------------------------------------------------------------
  function image(i) {
    if (!IMAGES[i]) return Promise.resolve(null);
    if (!cache[i]) {
      const img = new Image();
      cache[i] = new Promise(res => { img.onload = () => res(img); img.onerror = () => res(null); });
      img.src = IMAGES[i];
    }
    return cache[i];
  }
  function render() {
    const i = current, rec = frames[i];
    document.getElementById("frame-counter").textContent = String(rec.frame);
    document.getElementById("position").textContent = (i + 1) + " of " + frames.length;
    slider.value = String(i);
    document.querySelectorAll("#layers li").forEach(li =>
      li.classList.toggle("active", li.dataset.layer === active));
    highlight(rec);
    document.getElementById("info").textContent = infoText(layerById(active), rec);
    drawCharts(rec);
    drawLatent(rec);
    syncVideo(rec);
    image(i).then(img => {
      if (i !== current) return;
      view = zoomBox && zoomBox.checked ? zoomed(rec) : {x0: 0, y0: 0, k: scale};
      ctx.fillStyle = "#000"; ctx.fillRect(0, 0, canvas.width, canvas.height);
      if (img) {
        const f = img.naturalWidth / W, vw = canvas.width / view.k, vh = canvas.height / view.k;
        ctx.drawImage(img, view.x0 * f, view.y0 * f, vw * f, vh * f, 0, 0, canvas.width,
                      canvas.height);
      }
      for (const l of layers) {
        if (l.id === active || !visible[l.id]) continue;
        drawLayer(l, rec, 0.35);
      }
      const a = layerById(active);
      if (a && visible[a.id]) drawLayer(a, rec, 1);
      if (rec.dropped) {
        ctx.fillStyle = "rgba(0,0,0,.6)"; ctx.fillRect(0, 0, canvas.width, 22);
        ctx.fillStyle = "#ffd54f"; ctx.font = "bold 13px sans-serif";
        ctx.fillText("frame withheld from the tracker", 8, 16);
      }
      document.body.dataset.shown = String(i);
    });
  }
  function go(i) {
    current = Math.max(0, Math.min(frames.length - 1, i));
    render();
  }
  document.getElementById("prev").addEventListener("click", () => go(current - 1));
  document.getElementById("next").addEventListener("click", () => go(current + 1));
  slider.addEventListener("input", () => go(parseInt(slider.value, 10)));
  if (zoomBox) zoomBox.addEventListener("change", () => render());
  document.addEventListener("keydown", ev => {
    if (ev.target === slider) return;  // the slider moves itself and fires "input"
    if (ev.key === "ArrowRight") { go(current + 1); ev.preventDefault(); }
    else if (ev.key === "ArrowLeft") { go(current - 1); ev.preventDefault(); }
    else if (ev.key === "Home") { go(0); ev.preventDefault(); }
    else if (ev.key === "End") { go(frames.length - 1); ev.preventDefault(); }
  });
  window.pgmView = {go: go, get current() { return current; }, frames: frames.length,
                    setActive: setActive};
  go(0);
})();
"""
