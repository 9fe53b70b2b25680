"""Recording a run for the viewer: what the particles, messages and VB updates did.

``pgm track ... --record`` (``track(..., record=True)``, ``track_multi(..., record=True)``)
keeps, per recorded frame, what :mod:`pgm.app.view` needs to step through the run, in the
output folder's ``record/``:

* ``meta.json`` — the record's identity (``"id"``, also in ``run.json`` under
  ``"record"``), the settings, the image and thumbnail sizes, every variable (role,
  labels, which columns are its image position) and every factor (kind, variables);
  written at the start and rewritten when the record is closed (``"closed": true``, also
  after an interruption) with the number of frames recorded;
* ``graph.json`` — the graph as the engine runs it (:meth:`FactorGraph.to_dict`), for
  drawing when ``model.json`` is absent (an interrupted run);
* ``record.jsonl`` — one JSON object per recorded frame, appended and flushed as the run
  goes (a reader skips an incomplete last line); the fields are listed below;
* ``frames/NNNNNN.jpg`` — each recorded frame, downscaled so that its longer side is at
  most :attr:`RecordSettings.thumb_size` pixels.

**Bounded.** At most :attr:`RecordSettings.frames` frames are recorded: every
:attr:`RecordSettings.every`-th frame from the first (default every frame), until that many
are kept — so the *first* ``M`` frames by default, consecutive, which is what one steps
through when teaching. At most :attr:`RecordSettings.particles` particles are kept per
variable, per message and per intensity (for a plate, that many per variable split evenly
over its replicas, at least 10 each), chosen by :func:`subsample`: the heaviest half, plus
the other half drawn from the rest by systematic sampling with equal probabilities, each
with its own normalised weight (over *all* particles), so the picture shows both where the
mass is and how far the cloud spreads. No random number is drawn: a recorded run's results
are those of the same run without recording. Nothing is kept in memory between frames.

**When.** For the generic :class:`~pgm.inference.Engine`, particle beliefs are taken at the
``estimate`` stage (a hook: weighted and fused, before resampling — the weights that the
estimate used); the PHD intensity likewise (corrected, before resampling). The batched
particles of a plate's replicas are taken after the step (after resampling, whose events
are recorded, and after births and deaths, so that rows and identities agree).

Fields of one ``record.jsonl`` line
-----------------------------------
``i``, ``t``, ``frame``, ``image``
    Position among the recorded frames, engine step (0: the first frame, initialised from
    the priors), frame number, thumbnail path relative to ``record/``.
``variables``
    Per particle variable: ``x`` (image position of the kept particles, ``[[x, y], ...]``;
    the first two state columns for a variable without one), ``w`` (their normalised
    weights), ``n`` (all particles), ``shown_mass`` (the weight kept), ``ess`` (after
    weighting, before resampling), ``resampled``, ``estimate`` (the full state),
    ``own_mass`` (mixture fusion: the mass of its own particles), ``log_evidence``.
``messages``
    Per directed coupling message (particle BP): ``factor``, ``src``, ``dst``, ``x``, ``w``
    (normalised within the message), ``n``.
``sets``
    Per set variable (PHD): ``x``, ``w`` (normalised), ``n``, ``mass`` (expected number of
    targets), ``extracted`` (positions of the states extracted this frame), ``tracks``
    (``id``, ``x``, ``y``, ``coasting``, ``existence``), ``resampled_to``.
``vb``
    Per conjugate factor: ``elbo`` (after every state update of the fixed point),
    ``iterations``, ``sigma`` (σ̂ = sqrt(β/α) per component after the fixed point),
    ``noise`` (its noise variable).
``replicas``
    Plate models, per variable: one object per replica with ``id`` (0: not yet
    confirmed), ``reported``, ``existence``, ``x``, ``w``, ``n``, ``ess``, ``resampled``,
    ``estimate``; and ``plate``: ``births``, ``deaths``, ``missing``.
``measurements``
    The frame's detections, top-left ``[x, y, w, h]`` (multi-target runs).
``targets``
    What the run reports (and draws in ``annotated.mp4``): ``ids``, ``boxes`` (top-left
    ``x, y, w, h``), ``scores``, ``text``.
``dropped``
    The frame was withheld from the tracker (``drop_frames``).
"""

from __future__ import annotations

import json
import logging
import math
import uuid
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pgm.core.batched import BatchedParticles, is_batched
from pgm.core.boxes import box_columns
from pgm.core.errors import InputError
from pgm.core.graph import FactorGraph
from pgm.io.outputs import write_json

__all__ = ["RecordSettings", "Recorder", "record_settings", "subsample", "xy_columns",
           "RECORD_DIR", "RECORD_FORMAT", "read_record"]

log = logging.getLogger("pgm")

#: the folder of a run's output folder that holds its record
RECORD_DIR = "record"
#: the ``format`` field of ``meta.json``
RECORD_FORMAT = "pgm-record"
_VERSION = 1
_SUBSAMPLING = ("the heaviest half of the particles plus the other half drawn from the rest "
                "by systematic sampling with equal probabilities; weights are each particle's "
                "own normalised weight")


@dataclass(frozen=True)
class RecordSettings:
    """How much a recording keeps.

    Attributes
    ----------
    particles : int
        Particles kept per variable, per message and per intensity each recorded frame
        (for a plate: per variable, split over its replicas, at least 10 each).
    frames : int
        Frames recorded at most.
    every : int
        Record every ``every``-th frame (from the first) until ``frames`` are kept.
    thumb_size : int
        Longer side of the JPEG thumbnails, pixels (frames are never upscaled).
    jpeg_quality : int
        JPEG quality of the thumbnails, 1..100.
    """

    particles: int = 200
    frames: int = 300
    every: int = 1
    thumb_size: int = 480
    jpeg_quality: int = 80

    def __post_init__(self) -> None:
        for name, low, high in (("particles", 1, None), ("frames", 1, None), ("every", 1, None),
                                ("thumb_size", 16, None), ("jpeg_quality", 1, 100)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low or (
                    high is not None and v > high):
                bound = f"between {low} and {high}" if high else f"an integer >= {low}"
                raise InputError(f"record {name} must be {bound}, got {v!r}")


def record_settings(value: bool | RecordSettings | dict | None) -> RecordSettings | None:
    """The settings of a ``record=`` argument: ``None``/``False`` (off), ``True``
    (defaults), a :class:`RecordSettings` or a dict of its fields."""
    if value is None or value is False:
        return None
    if value is True:
        return RecordSettings()
    if isinstance(value, RecordSettings):
        return value
    if isinstance(value, dict):
        unknown = sorted(set(value) - set(RecordSettings.__dataclass_fields__))
        if unknown:
            raise InputError(f"unknown record settings {unknown}")
        return RecordSettings(**value)
    raise InputError(f"record must be True, False, a RecordSettings or a dict, got "
                     f"{type(value).__name__}")


def subsample(weights: np.ndarray, k: int) -> np.ndarray:
    """Indices (increasing) of at most ``k`` particles to show out of ``len(weights)``.

    All of them when there are at most ``k``; else the ``ceil(k/2)`` heaviest plus
    ``floor(k/2)`` of the rest by systematic sampling with equal probabilities (every
    ``(N - ceil(k/2)) / floor(k/2)``-th in index order, at the middle of each stratum).
    Deterministic: no random number is drawn.
    """
    w = np.asarray(weights, dtype=float).reshape(-1)
    n = w.size
    if n <= k:
        return np.arange(n)
    top = (k + 1) // 2
    order = np.argsort(-np.nan_to_num(w, nan=-np.inf), kind="stable")
    rest = np.sort(order[top:])
    m = k - top
    picked = rest[((np.arange(m) + 0.5) * rest.size / m).astype(int)] if m else rest[:0]
    return np.sort(np.concatenate([order[:top], picked]))


def xy_columns(graph: FactorGraph, variable: str) -> tuple[list[int], bool]:
    """Columns of ``variable`` holding an image position (by its labels) and whether it
    has one; without one, its first two columns (or its only one, twice)."""
    v = graph.variables[variable]
    labels = v.labels or ()
    for pair in (("cx", "cy"), ("px", "py"), ("x", "y")):
        if all(name in labels for name in pair):
            return [labels.index(pair[0]), labels.index(pair[1])], True
    return ([0, 1] if v.dim >= 2 else [0, 0]), False


def _box_columns(graph: FactorGraph, variable: str) -> list[int] | None:
    return box_columns(graph.variables[variable].labels)


# -- numbers as JSON (finite floats, rounded; NaN and infinities become null) ---------
def _num(values: Any, digits: int = 2) -> Any:
    r = np.round(np.asarray(values, dtype=float), digits)
    if np.isfinite(r).all():
        return r.tolist()
    return _nulls(r)


def _nulls(a: np.ndarray) -> Any:
    if a.ndim == 0:
        v = float(a)
        return v if math.isfinite(v) else None
    return [_nulls(row) for row in a]


def _sig(values: Any, digits: int = 3) -> list:
    """Floats to ``digits`` significant digits (weights span many orders of magnitude)."""
    out = []
    for v in np.asarray(values, dtype=float).reshape(-1).tolist():
        out.append(float(f"{v:.{digits}g}") if math.isfinite(v) else None)
    return out


def _scalar(v: Any, digits: int = 4) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return round(f, digits) if math.isfinite(f) else None


def _normalised(log_weights: np.ndarray) -> np.ndarray:
    lw = np.asarray(log_weights, dtype=float).reshape(-1)
    if lw.size == 0 or not np.isfinite(lw).any():
        return np.zeros(lw.size)
    m = lw[np.isfinite(lw)].max()
    w = np.exp(np.where(np.isfinite(lw), lw - m, -np.inf))
    return w / w.sum()


def read_record(folder: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """``meta.json`` and the frames of ``record.jsonl`` in a record folder (an incomplete
    last line, left by a run that was killed, is skipped)."""
    folder = Path(folder)
    meta_path, lines_path = folder / "meta.json", folder / "record.jsonl"
    if not meta_path.is_file() or not lines_path.is_file():
        raise InputError(f"{folder} holds no record (meta.json and record.jsonl): run "
                         f"'pgm track ... --record' first")
    try:
        meta = json.loads(meta_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{meta_path} is not valid JSON: {exc}") from None
    if not isinstance(meta, dict) or meta.get("format") != RECORD_FORMAT:
        raise InputError(f"{meta_path} is not a pgm record")
    frames = []
    with lines_path.open(encoding="utf-8") as fh:
        for line in fh:
            try:
                frames.append(json.loads(line))
            except json.JSONDecodeError:
                break  # the incomplete last line of a killed run
    return meta, frames


class Recorder:
    """Write a run's record into ``out_dir/record`` as it goes (see the module's notes).

    Parameters
    ----------
    out_dir : Path
        The run's output folder.
    engine : Engine
        The engine that runs the graph (a hook is added to an :class:`Engine`).
    settings : RecordSettings
    fps : float
        The source's frame rate (for the viewer's video).

    Notes
    -----
    An earlier record in ``out_dir/record`` (its ``meta.json``, ``graph.json``,
    ``record.jsonl`` and ``frames/*.jpg``) and an earlier ``out_dir/view.html`` are
    removed first; other files are left alone.
    """

    def __init__(self, out_dir: str | Path, engine: Any, settings: RecordSettings, *,
                 fps: float = 25.0):
        self.settings = settings
        self.folder = Path(out_dir) / RECORD_DIR
        self.engine = engine
        self.graph: FactorGraph = engine.graph
        self.id = uuid.uuid4().hex
        self.fps = float(fps) if fps and math.isfinite(fps) and fps > 0 else 25.0
        self.frames = 0
        self.image_size: tuple[int, int] | None = None
        self.thumb_size: tuple[int, int] | None = None
        self._pending: dict[str, Any] = {}
        self._clear(Path(out_dir))
        self._fh = (self.folder / "record.jsonl").open("w", encoding="utf-8")
        self._write_meta(closed=False)
        try:
            write_json(self.folder / "graph.json", self.graph.to_dict())
        except (TypeError, ValueError) as exc:  # a factor that cannot be saved: no drawing
            log.warning("record: the graph cannot be saved for the viewer (%s)", exc)
        if hasattr(engine, "add_hook"):
            engine.add_hook("estimate", self._hook)

    # -- set-up ------------------------------------------------------------------------
    def _clear(self, out: Path) -> None:
        folder = self.folder
        if folder.is_symlink():
            folder.unlink()
        elif folder.exists() and not folder.is_dir():
            raise InputError(f"{folder} exists and is not a folder; remove it to record")
        try:
            (folder / "frames").mkdir(parents=True, exist_ok=True)
            for name in ("meta.json", "graph.json", "record.jsonl"):
                p = folder / name
                if p.is_symlink() or p.is_file():
                    p.unlink()
            for p in (folder / "frames").glob("*.jpg"):
                if p.is_symlink() or p.is_file():
                    p.unlink()
            view = out / "view.html"
            if view.is_symlink() or view.is_file():
                view.unlink()
        except OSError as exc:
            raise InputError(f"cannot prepare the record folder {folder}: "
                             f"{exc.strerror or exc}") from None

    def _variables(self) -> dict[str, Any]:
        out = {}
        plated = self.graph.plate_variables
        for name, v in self.graph.variables.items():
            cols, image = xy_columns(self.graph, name)
            out[name] = {"role": v.role, "dim": v.dim, "labels": list(v.labels or ()),
                         "xy": cols, "image": image, "box": _box_columns(self.graph, name),
                         "plate": name in plated}
        return out

    def _write_meta(self, closed: bool) -> None:
        g = self.graph
        meta = {"format": RECORD_FORMAT, "version": _VERSION, "id": self.id, "model": g.name,
                "engine": type(self.engine).__name__, "fps": self.fps,
                "image_size": list(self.image_size) if self.image_size else None,
                "thumb_size": list(self.thumb_size) if self.thumb_size else None,
                "settings": asdict(self.settings), "subsampling": _SUBSAMPLING,
                "output": list(g.output),
                "num_particles": {k: int(v) for k, v in
                                  dict(getattr(self.engine, "num_particles", {})).items()},
                "plates": [{"name": p.name, "variables": list(p.variables),
                            "size_label": p.size_label} for p in g.plates],
                "variables": self._variables(),
                "factors": {f.name: {"kind": f.kind, "type": type(f).__name__,
                                     "variables": list(f.variables)}
                            for f in g.factors.values()},
                "frames_recorded": self.frames, "closed": bool(closed)}
        write_json(self.folder / "meta.json", meta)

    def summary(self) -> dict[str, Any]:
        """What ``run.json`` says about the record (``"record"``)."""
        return {"dir": RECORD_DIR, "id": self.id, "frames_recorded": self.frames,
                "settings": asdict(self.settings)}

    # -- per frame -----------------------------------------------------------------------
    def wants(self, t: int) -> bool:
        """Whether engine step ``t`` (0-based) is recorded."""
        return t % self.settings.every == 0 and self.frames < self.settings.frames

    def _hook(self, engine, stage, frame, record) -> None:  # noqa: ARG002 - hook signature
        """At the estimate stage: keep the weighted beliefs (before resampling) of this
        frame, if it is recorded (immutable objects: no copy)."""
        if self.wants(engine.t):
            self._pending = {v: b for v, b in engine.beliefs.items()
                             if self.graph.variables[v].role != "noise"}

    def write(self, engine: Any, record: Any, image: np.ndarray | None, *,
              targets: dict[str, Any] | None = None, detections: Any = None,
              dropped: bool = False) -> bool:
        """Record the step just taken (``engine.t - 1``) if it is a recorded one.

        Parameters
        ----------
        engine : Engine
            After its step.
        record : StepRecord
            The step's record.
        image : ndarray
            The frame (BGR or grey), for the thumbnail.
        targets : dict, optional
            ``ids``, ``boxes`` (top-left ``x, y, w, h``), ``scores``, ``text``: what the
            run reports for this frame.
        detections : Detections, optional
            The frame's measurements.
        dropped : bool
            The frame was withheld from the tracker.

        Returns
        -------
        bool
            Whether the frame was recorded.
        """
        t = engine.t - 1
        pending, self._pending = self._pending, {}
        if not self.wants(t):
            return False
        number = int(record.frame)
        line: dict[str, Any] = {"i": self.frames, "t": t, "frame": number,
                                "image": self._thumbnail(image, number)}
        if dropped:
            line["dropped"] = True
        if any(is_batched(b) for b in record.beliefs.values()):
            self._plate(line, engine, record)
        else:
            self._engine(line, engine, record, pending)
        if detections is not None and len(getattr(detections, "boxes", ())):
            line["measurements"] = _num(np.asarray(detections.boxes, dtype=float)
                                        .reshape(-1, 4), 1)
        if targets is not None:
            line["targets"] = {"ids": [int(i) for i in np.asarray(targets["ids"]).reshape(-1)],
                               "boxes": _num(np.asarray(targets["boxes"], dtype=float)
                                             .reshape(-1, 4), 1),
                               "scores": _sig(targets.get("scores", [])),
                               "text": str(targets.get("text", ""))}
        self._fh.write(json.dumps(line, separators=(",", ":"), allow_nan=False) + "\n")
        self._fh.flush()
        self.frames += 1
        return True

    def _thumbnail(self, image: np.ndarray | None, number: int) -> str | None:
        if image is None:
            return None
        h, w = image.shape[:2]
        if self.image_size is None:
            self.image_size = (int(w), int(h))
            s = min(1.0, self.settings.thumb_size / max(w, h))
            self.thumb_size = (max(1, int(round(w * s))), max(1, int(round(h * s))))
            self._write_meta(closed=False)
        small = image
        if (w, h) != self.thumb_size:
            small = cv2.resize(image, self.thumb_size, interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY,
                                               self.settings.jpeg_quality])
        if not ok:
            return None
        name = f"frames/{number:06d}.jpg"
        (self.folder / name).write_bytes(buf.tobytes())
        return name

    def _cloud(self, x: np.ndarray, w: np.ndarray, cols: list[int], k: int) -> dict[str, Any]:
        idx = subsample(w, k)
        return {"x": _num(x[idx][:, cols], 1), "w": _sig(w[idx]), "n": int(w.size),
                "shown_mass": _scalar(w[idx].sum())}

    def _engine(self, line: dict, engine: Any, record: Any, pending: dict) -> None:
        g, k = self.graph, self.settings.particles
        variables, sets = {}, {}
        for name, var in g.variables.items():
            if var.role == "noise":
                continue
            b = pending.get(name, record.beliefs.get(name))
            if b is None:
                continue
            cols, _ = xy_columns(g, name)
            if var.role == "set":
                sets[name] = self._set(name, b, record, cols)
                continue
            x = np.asarray(b.x, dtype=float)
            w = np.asarray(b.weights, dtype=float) if b.num else np.zeros(0)
            entry = self._cloud(x, w, cols, k)
            info = record.info.get(name)
            info = info if isinstance(info, Mapping) else {}
            entry.update(ess=_scalar(record.ess.get(name), 2),
                         resampled=bool(record.resampled.get(name, False)),
                         estimate=_num(record.estimates.get(name, []), 2),
                         own_mass=_scalar(info.get("own_mass")),
                         log_evidence=_scalar(record.log_evidence.get(name)))
            variables[name] = entry
        line["variables"] = variables
        if sets:
            line["sets"] = sets
        messages = []
        coupling_of = self._coupling_of(engine)
        for (src, dst), m in record.messages.items():
            cols, _ = xy_columns(g, dst)
            x = np.asarray(getattr(m, "x", np.zeros((0, g.variables[dst].dim))), dtype=float)
            w = _normalised(getattr(m, "log_weights", np.zeros(x.shape[0])))
            if x.ndim != 2 or x.shape[0] != w.size:
                continue
            messages.append({"factor": coupling_of.get((src, dst)), "src": src, "dst": dst,
                             **self._cloud(x, w, cols, k)})
        if messages:
            line["messages"] = messages
        vb = {}
        for f in g.factors_by_kind("conjugate"):
            info = record.info.get(f.name)
            if not isinstance(info, Mapping) or "elbo" not in info:
                continue
            r_hat = np.asarray(info.get("r_hat", []), dtype=float).reshape(-1)
            vb[f.name] = {"elbo": _sig(info.get("elbo", []), 8),
                          "iterations": int(info.get("iterations", len(info["elbo"]))),
                          "sigma": _sig(np.sqrt(np.maximum(r_hat, 0.0)), 4),
                          "noise": f.variables[0]}
        if vb:
            line["vb"] = vb

    def _coupling_of(self, engine: Any) -> dict[tuple[str, str], str]:
        """``(src, dst)`` → the coupling factor that sends that message (this engine's
        schedule)."""
        out: dict[tuple[str, str], str] = {}
        schedule = getattr(engine, "schedule", None)
        for _stage, items in getattr(schedule, "phases", []):
            for item in items:
                if isinstance(item, tuple) and len(item) == 3:
                    out.setdefault((item[1], item[2]), item[0])
        return out

    def _set(self, name: str, b: Any, record: Any, cols: list[int]) -> dict[str, Any]:
        n = int(getattr(b, "num", 0))
        x = np.asarray(b.x, dtype=float).reshape(n, self.graph.variables[name].dim)
        w = np.asarray(b.weights, dtype=float) if n else np.zeros(0)
        entry = self._cloud(x, w, cols, self.settings.particles)
        entry["mass"] = _scalar(getattr(b, "expected_count", b.mass if n else 0.0))
        est = record.estimates.get(name)
        if isinstance(est, Mapping):  # a PHD variable's estimate (IntensityEstimate)
            ext = np.asarray(est.get("extracted", np.zeros((0, x.shape[1]))), dtype=float)
            entry["extracted"] = _num(ext.reshape(-1, x.shape[1])[:, cols], 1) if ext.size \
                else []
            states = np.asarray(est.get("states", []), dtype=float).reshape(-1, x.shape[1])
            ids = np.asarray(est.get("ids", []), dtype=int).reshape(-1)
            coast = np.asarray(est.get("coasting", np.zeros(len(ids))), dtype=bool).reshape(-1)
            ex = np.asarray(est.get("existence", np.ones(len(ids))), dtype=float).reshape(-1)
            entry["tracks"] = [{"id": int(i), "x": _scalar(s[cols[0]], 1),
                                "y": _scalar(s[cols[1]], 1), "coasting": bool(c),
                                "existence": _scalar(e, 3)}
                               for i, s, c, e in zip(ids, states, coast, ex, strict=False)]
        info = record.info.get(name)
        if isinstance(info, Mapping) and "particles" in info:
            entry["resampled_to"] = int(info["particles"])
        return entry

    def _plate(self, line: dict, engine: Any, record: Any) -> None:
        g = self.graph
        info = record.plate if record.plate is not None else {}
        ids = np.asarray(info.get("ids", []), dtype=int).reshape(-1)
        reported = np.asarray(info.get("reported", np.zeros(len(ids))), dtype=bool).reshape(-1)
        existence = np.asarray(info.get("existence", np.ones(len(ids))),
                               dtype=float).reshape(-1)
        replicas = {}
        for name in g.variables:
            b = record.beliefs.get(name)
            if not isinstance(b, BatchedParticles):  # Gaussian or noise beliefs: no cloud
                continue
            x, lw = b.x, b.log_weights
            kk = x.shape[0]
            per = max(10, -(-self.settings.particles // max(kk, 1)))
            cols, _ = xy_columns(g, name)
            ess = np.asarray(record.ess.get(name, np.full(kk, np.nan)), dtype=float)
            res = np.asarray(record.resampled.get(name, np.zeros(kk, bool)), dtype=bool)
            if ess.shape != (kk,):  # a missing frame: no weight stage
                ess = np.full(kk, np.nan)
            if res.shape != (kk,):
                res = np.zeros(kk, bool)
            est = np.asarray(record.estimates.get(name, np.zeros((kk, x.shape[-1]))),
                             dtype=float).reshape(kk, -1)
            rows = []
            for r in range(kk):
                w = _normalised(lw[r])
                rows.append({"id": int(ids[r]) if r < ids.size else 0,
                             "reported": bool(reported[r]) if r < reported.size else False,
                             "existence": _scalar(existence[r], 3) if r < existence.size
                             else None,
                             **self._cloud(np.asarray(x[r], dtype=float), w, cols, per),
                             "ess": _scalar(ess[r], 2) if r < ess.size else None,
                             "resampled": bool(res[r]) if r < res.size else False,
                             "estimate": _num(est[r], 2)})
            replicas[name] = rows
        line["replicas"] = replicas
        line["plate"] = {"births": int(info.get("births", 0)),
                         "deaths": [int(d) for d in np.asarray(info.get("deaths", []))
                                    .reshape(-1)],
                         "missing": bool(info.get("missing", False))}

    def close(self) -> None:
        """Close ``record.jsonl`` and rewrite ``meta.json`` with the frames recorded."""
        if self._fh is not None and not self._fh.closed:
            self._fh.close()
            try:
                self._write_meta(closed=True)
            except InputError as exc:  # the run's own outcome matters more
                log.warning("record: %s", exc)
