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

The page's HTML template, style and script are package data beside this module
(``pgm/app/viewer/viewer.html``, ``viewer.css``, ``viewer.js``), read when a page is
written. The template marks where the title, style, graph, video, data, images and
script go; all seven are substituted in one regular-expression pass, so a value that
happens to contain another marker is never substituted again.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
from importlib.resources import files
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
def _viewer_file(name: str) -> str:
    """The text of one of the page's files: ``pgm/app/viewer/NAME`` (package data)."""
    return (files("pgm.app") / "viewer" / name).read_text(encoding="utf-8")


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
    """The thumbnail a record line names, inside the record folder: by name (relative,
    without ``..``) and where it resolves (a symbolic link, of the file or of a folder on
    its way, to anything outside the record folder is refused): a crafted record must not
    make the page embed the user's other files."""
    parts = Path(name).parts
    if not name or Path(name).is_absolute() or ".." in parts or "\\" in name:
        raise InputError(f"{where}: image {name!r} is not a path inside {folder} (the "
                         f"record names its thumbnails relative to it, e.g. "
                         f"frames/000001.jpg)")
    path = folder / name
    real, root = path.resolve(), folder.resolve()
    if path.exists() and not real.is_relative_to(root):
        raise InputError(f"{where}: image {name!r} resolves to {real}, outside {root} (a "
                         f"symbolic link out of the record is not followed)")
    return path


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
    parts = {"TITLE": html.escape(title), "CSS": _viewer_file("viewer.css"),
             "GRAPH": graph_svg(graph),
             "VIDEO": "" if video is None else
             f'<video id="video" controls muted playsinline preload="auto" '
             f'src="{html.escape(video["src"])}"></video>',
             "DATA": _script_json(data), "IMAGES": _script_json(images),
             "JS": _viewer_file("viewer.js")}
    # one pass over the template: text substituted in is never searched again
    page = re.sub(r"__(TITLE|CSS|GRAPH|VIDEO|DATA|IMAGES|JS)__", lambda m: parts[m.group(1)],
                  _viewer_file("viewer.html"))
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
