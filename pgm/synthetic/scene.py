"""Synthetic tracking scenes with exact ground truth.

A :class:`Scene` is a list of moving rectangular objects made of horizontal colour
bands (a person is a red top over a blue bottom, a face three bands), drawn over a
smooth low-contrast background, with rectangular *occluders* ("magazines": light grey
pages with dark text lines) drawn on top of every object. Rendering is exact in the
area sense: a pixel ``(row i, column j)`` covers ``[j, j+1) x [i, i+1)`` (see
:mod:`pgm.core.boxes`) and a partly covered pixel blends the object's colour by the covered
fraction, so the ground-truth boxes are exact and the visible fraction of any
horizontal band of an object is computed geometrically (:meth:`Scene.band_visibility`).

Depth order: objects are drawn in list order (a later object hides an earlier one) and
every occluder is drawn over every object. The visible fraction of a box (or band) is
its area that lies inside the image and is not covered by anything drawn over it,
divided by its whole area.

Frames are numbered from 1 (as in MOTChallenge and OTB); boxes are top-left
``(x, y, w, h)`` in 0-based continuous pixel coordinates. All randomness (background,
textures, per-frame pixel noise, detections) comes from the ``numpy.random.Generator``
passed in; the geometry (boxes, visibilities) does not depend on it.

Presets: :func:`demo_scene` (default input of ``pgm demo``), :func:`part_occlusion_scene`
(one band of an object hidden for a stretch of frames) and :func:`multi_target_scene`
(births, deaths, crossings; detections with clutter through
:meth:`SyntheticSequence.write_mot`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.core.rng import as_generator

__all__ = [
    "ObjectSpec",
    "OccluderSpec",
    "ObjectTruth",
    "Scene",
    "SyntheticSequence",
    "MAGAZINE_COLOR",
    "demo_scene",
    "part_occlusion_scene",
    "multi_target_scene",
]

#: Default occluder page colour (BGR): a light, unsaturated grey, far from band colours.
MAGAZINE_COLOR: tuple[int, int, int] = (178, 182, 186)

_RED = (40, 40, 200)
_BLUE = (190, 90, 30)
_GREEN = (60, 170, 50)


# --------------------------------------------------------------------------- validation


def _finite(name: str, values: Sequence[float], n: int | None = None) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a sequence of numbers, got {values!r}") from None
    if n is not None and len(out) != n:
        raise InputError(f"{name} must have {n} values, got {len(out)}")
    if not all(math.isfinite(v) for v in out):
        raise InputError(f"{name} must be finite, got {values!r}")
    return out


def _color(name: str, c: Sequence[float]) -> tuple[float, float, float]:
    out = _finite(name, c, 3)
    if not all(0.0 <= v <= 255.0 for v in out):
        raise InputError(f"{name} must be a BGR triple in [0, 255], got {c!r}")
    return out  # type: ignore[return-value]


def _box(name: str, box: Sequence[float]) -> tuple[float, float, float, float]:
    out = _finite(name, box, 4)
    if out[2] <= 0 or out[3] <= 0:
        raise InputError(f"{name} must have positive width and height, got {box!r}")
    return out  # type: ignore[return-value]


def _nonneg(name: str, v: float) -> float:
    v = float(v)
    if not math.isfinite(v) or v < 0:
        raise InputError(f"{name} must be a finite number >= 0, got {v!r}")
    return v


def _frame_range(start: int, end: int | None) -> tuple[int, int | None]:
    if isinstance(start, bool) or not isinstance(start, (int, np.integer)) or start < 1:
        raise InputError(f"start must be a 1-based frame number >= 1, got {start!r}")
    if end is not None:
        if isinstance(end, bool) or not isinstance(end, (int, np.integer)) or end <= start:
            raise InputError(f"end must be None or a frame number > start={start}, got {end!r}")
        end = int(end)
    return int(start), end


def _check_n_frames(n_frames: int) -> int:
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)):
        raise InputError(f"n_frames must be a positive integer, got {n_frames!r}")
    if n_frames <= 0:
        raise InputError(f"n_frames must be a positive integer, got {n_frames}")
    return int(n_frames)


# --------------------------------------------------------------------------- specs


@dataclass
class ObjectSpec:
    """A moving object made of horizontal colour bands.

    Parameters
    ----------
    box : (x, y, w, h)
        Top-left box, 0-based, at frame ``start``.
    colors : sequence of BGR triples
        Band colours from top to bottom; the box is split into ``len(colors)`` bands of
        equal height.
    velocity : (vx, vy)
        Constant velocity of the box centre, pixels per frame.
    wobble : (ax, ay)
        Amplitude (pixels) of a sinusoid added to the centre:
        ``a * sin(2 pi t / wobble_period + wobble_phase)`` with ``t = frame - start``.
    wobble_period, wobble_phase : float
        Period (frames) and phase (radians) of the wobble.
    scale : float
        Per-frame size factor: ``w(t) = w * scale**t`` (same for ``h``), about the centre.
    texture : float
        Standard deviation (grey levels) of the object's fixed smooth texture, which
        moves and scales with the object; zero mean within each band.
    noise : float
        Standard deviation of the per-pixel noise, drawn independently every frame.
    start, end : int
        The object exists in frames ``start <= frame < end`` (1-based; ``end=None``: to
        the end of the sequence).
    name : str
        Free label.
    """

    box: tuple[float, float, float, float]
    colors: Sequence[tuple[int, int, int]] = (_RED, _BLUE)
    velocity: tuple[float, float] = (0.0, 0.0)
    wobble: tuple[float, float] = (0.0, 0.0)
    wobble_period: float = 30.0
    wobble_phase: float = 0.0
    scale: float = 1.0
    texture: float = 14.0
    noise: float = 5.0
    start: int = 1
    end: int | None = None
    name: str = ""

    def __post_init__(self) -> None:
        self.box = _box("object box", self.box)
        colors = list(self.colors)
        if not colors:
            raise InputError("object colors must hold at least one BGR band colour")
        self.colors = tuple(_color("object band colour", c) for c in colors)
        self.velocity = _finite("object velocity", self.velocity, 2)  # type: ignore[assignment]
        self.wobble = _finite("object wobble", self.wobble, 2)  # type: ignore[assignment]
        self.wobble_period = float(self.wobble_period)
        if not math.isfinite(self.wobble_period) or self.wobble_period <= 0:
            raise InputError(f"wobble_period must be > 0, got {self.wobble_period}")
        self.wobble_phase = _finite("wobble_phase", [self.wobble_phase])[0]
        self.scale = float(self.scale)
        if not math.isfinite(self.scale) or self.scale <= 0:
            raise InputError(f"object scale factor must be > 0, got {self.scale}")
        self.texture = _nonneg("object texture", self.texture)
        self.noise = _nonneg("object noise", self.noise)
        self.start, self.end = _frame_range(self.start, self.end)

    @property
    def n_bands(self) -> int:
        return len(self.colors)

    def alive(self, frame: int) -> bool:
        """Whether the object exists in ``frame`` (1-based)."""
        return self.start <= frame and (self.end is None or frame < self.end)

    def box_at(self, frame: int) -> np.ndarray:
        """Top-left box ``(x, y, w, h)`` at ``frame`` (extrapolated if not alive)."""
        x, y, w, h = self.box
        t = float(frame - self.start)
        s = self.scale ** t
        arg = 2.0 * math.pi * t / self.wobble_period + self.wobble_phase
        cx = x + w / 2.0 + self.velocity[0] * t + self.wobble[0] * math.sin(arg)
        cy = y + h / 2.0 + self.velocity[1] * t + self.wobble[1] * math.sin(arg)
        w1, h1 = w * s, h * s
        return np.array([cx - w1 / 2.0, cy - h1 / 2.0, w1, h1])


@dataclass
class OccluderSpec:
    """A rectangle drawn over every object: by default a grey "magazine" page.

    Parameters
    ----------
    box : (x, y, w, h)
        Top-left box, 0-based, at frame ``start``.
    color : BGR triple
        Page colour (default :data:`MAGAZINE_COLOR`, a light unsaturated grey).
    velocity : (vx, vy)
        Constant velocity, pixels per frame (``(0, 0)``: static).
    texture : float
        Contrast of the pattern: dark "text lines" are ``texture`` grey levels darker
        than the page (``pattern="magazine"``), or smooth noise of that standard
        deviation (``pattern="noise"``).
    noise : float
        Per-pixel noise standard deviation, drawn independently every frame.
    start, end : int
        Present in frames ``start <= frame < end`` (1-based; ``end=None``: to the end).
    """

    box: tuple[float, float, float, float]
    color: tuple[int, int, int] = MAGAZINE_COLOR
    velocity: tuple[float, float] = (0.0, 0.0)
    texture: float = 80.0
    noise: float = 3.0
    pattern: str = "magazine"
    start: int = 1
    end: int | None = None

    def __post_init__(self) -> None:
        self.box = _box("occluder box", self.box)
        self.color = _color("occluder colour", self.color)  # type: ignore[assignment]
        self.velocity = _finite("occluder velocity", self.velocity, 2)  # type: ignore[assignment]
        self.texture = _nonneg("occluder texture", self.texture)
        self.noise = _nonneg("occluder noise", self.noise)
        if self.pattern not in ("magazine", "noise"):
            raise InputError(
                f"occluder pattern must be 'magazine' or 'noise', got {self.pattern!r}")
        self.start, self.end = _frame_range(self.start, self.end)

    def alive(self, frame: int) -> bool:
        return self.start <= frame and (self.end is None or frame < self.end)

    def box_at(self, frame: int) -> np.ndarray:
        x, y, w, h = self.box
        t = float(frame - self.start)
        return np.array([x + self.velocity[0] * t, y + self.velocity[1] * t, w, h])


@dataclass(eq=False)
class ObjectTruth:
    """Ground truth of one object over the frames where it is in the image.

    ``frames`` (K,) 1-based frame numbers where the object exists and its box overlaps
    the image; ``boxes`` (K, 4) top-left ``(x, y, w, h)`` 0-based (not clipped to the
    image); ``visibility`` (K,) visible fraction of the box; ``id`` the 1-based MOT id.
    """

    id: int
    frames: np.ndarray
    boxes: np.ndarray
    visibility: np.ndarray


# --------------------------------------------------------------------------- geometry


def _corners(box: np.ndarray) -> tuple[float, float, float, float]:
    x, y, w, h = (float(v) for v in box)
    return x, y, x + w, y + h


def _visible_area(rect: tuple[float, float, float, float],
                  covers: list[tuple[float, float, float, float]],
                  width: int, height: int) -> float:
    """Area of ``rect`` (x0, y0, x1, y1) inside the image and outside every cover."""
    x0, y0 = max(rect[0], 0.0), max(rect[1], 0.0)
    x1, y1 = min(rect[2], float(width)), min(rect[3], float(height))
    if x1 <= x0 or y1 <= y0:
        return 0.0
    cl = []
    for a, b, c, d in covers:
        a, b, c, d = max(a, x0), max(b, y0), min(c, x1), min(d, y1)
        if c > a and d > b:
            cl.append((a, b, c, d))
    if not cl:
        return (x1 - x0) * (y1 - y0)
    xs = np.unique(np.array([x0, x1] + [v for r in cl for v in (r[0], r[2])]))
    ys = np.unique(np.array([y0, y1] + [v for r in cl for v in (r[1], r[3])]))
    mx, my = (xs[:-1] + xs[1:]) / 2.0, (ys[:-1] + ys[1:]) / 2.0
    covered = np.zeros((my.size, mx.size), dtype=bool)
    for a, b, c, d in cl:
        covered |= ((my >= b) & (my < d))[:, None] & ((mx >= a) & (mx < c))[None, :]
    cells = np.diff(ys)[:, None] * np.diff(xs)[None, :]
    return float(cells[~covered].sum())


# --------------------------------------------------------------------------- textures


def _smooth_noise(rng: np.random.Generator, h: int, w: int, cells_h: int, cells_w: int,
                  channels: int) -> np.ndarray:
    """Unit-variance smooth noise ``(h, w, channels)`` float32 (cubic upsampling)."""
    low = rng.standard_normal((max(cells_h, 2), max(cells_w, 2), channels), dtype=np.float32)
    out = cv2.resize(low, (w, h), interpolation=cv2.INTER_CUBIC).reshape(h, w, channels)
    out -= out.mean()
    sd = float(out.std())
    return out / sd if sd > 0 else out


def _object_texture(rng: np.random.Generator, spec: ObjectSpec) -> np.ndarray:
    n = spec.n_bands
    th, tw = 24 * n, 24
    lum = _smooth_noise(rng, th, tw, 3 * n, 4, 1) + 0.5 * _smooth_noise(rng, th, tw, 10 * n, 10, 1)
    tex = lum + 0.3 * _smooth_noise(rng, th, tw, 4 * n, 4, 3)
    sd = float(tex.std())
    tex = tex / sd if sd > 0 else tex
    for k in range(n):  # zero mean within each band, so a band's mean colour is its colour
        band = tex[k * 24:(k + 1) * 24]
        band -= band.mean(axis=(0, 1), keepdims=True)
    return (tex * spec.texture).astype(np.float32)


def _occluder_texture(rng: np.random.Generator, spec: OccluderSpec) -> np.ndarray:
    th, tw = max(int(math.ceil(spec.box[3])), 1), max(int(math.ceil(spec.box[2])), 1)
    if spec.pattern == "noise":
        return (_smooth_noise(rng, th, tw, th // 8 + 2, tw // 8 + 2, 3) * spec.texture)
    # magazine page: a soft paper grain, a dark title bar, then lines of "words"
    tex = 0.06 * spec.texture * _smooth_noise(rng, th, tw, th // 6 + 2, tw // 6 + 2, 1)
    tex = np.repeat(tex, 3, axis=2)
    margin = max(2, tw // 10)
    row, pitch, line_h = max(2, th // 12), 6, 2
    title_h = min(5, max(th // 8, 1))
    if row + title_h < th:
        tex[row:row + title_h, margin:tw - margin] -= 0.8 * spec.texture
        row += title_h + 3
    while row + line_h <= th - 2:
        col = margin
        while col < tw - margin:
            word = int(rng.integers(3, 12))
            tex[row:row + line_h, col:min(col + word, tw - margin)] -= spec.texture
            col += word + 3
        row += pitch
    return tex.astype(np.float32)


def _sensor_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma: float) -> np.ndarray:
    """Zero-mean noise of standard deviation ``sigma``, float32: the sum of two uniform
    random bytes (a triangular, nearly Gaussian law), five times faster than normals."""
    n = int(np.prod(shape))
    b = np.frombuffer(rng.bytes(2 * n), dtype=np.uint8)
    out = b[:n].astype(np.float32)
    out += b[n:]
    out -= 255.0
    out *= sigma / math.sqrt((256.0**2 - 1.0) / 6.0)
    return out.reshape(shape)


def _coverage(lo: float, hi: float, idx: np.ndarray) -> np.ndarray:
    """Covered fraction of each unit cell ``[i, i+1)`` by ``[lo, hi)``."""
    return np.clip(np.minimum(idx + 1.0, hi) - np.maximum(idx.astype(float), lo), 0.0, 1.0)


def _draw(img: np.ndarray, box: np.ndarray, colors: np.ndarray, tex: np.ndarray,
          noise: float, rng: np.random.Generator) -> None:
    """Blend a banded textured rectangle into ``img`` (float32, in place)."""
    H, W = img.shape[:2]
    x, y, w, h = (float(v) for v in box)
    j0, j1 = max(0, math.floor(x)), min(W, math.ceil(x + w))
    i0, i1 = max(0, math.floor(y)), min(H, math.ceil(y + h))
    if j1 <= j0 or i1 <= i0:
        return
    cols, rows = np.arange(j0, j1), np.arange(i0, i1)
    cx = _coverage(x, x + w, cols)
    n = colors.shape[0]
    edges = y + h * np.arange(n + 1) / n
    cyk = np.stack([_coverage(edges[k], edges[k + 1], rows) for k in range(n)])  # (n, R)
    cy = cyk.sum(axis=0)
    row_color = (cyk.T @ colors) / np.where(cy > 0, cy, 1.0)[:, None]  # (R, 3)
    th, tw = tex.shape[:2]
    ti = np.clip(np.floor((rows + 0.5 - y) / h * th).astype(int), 0, th - 1)
    tj = np.clip(np.floor((cols + 0.5 - x) / w * tw).astype(int), 0, tw - 1)
    patch = row_color[:, None, :].astype(np.float32) + tex[ti[:, None], tj[None, :]]
    if noise > 0:
        patch += noise * rng.standard_normal(patch.shape, dtype=np.float32)
    alpha = (cy[:, None] * cx[None, :]).astype(np.float32)[..., None]
    region = img[i0:i1, j0:j1]
    region += alpha * (patch - region)


# --------------------------------------------------------------------------- scene


class Scene:
    """Objects and occluders over a smooth background.

    Parameters
    ----------
    objects : sequence of ObjectSpec
        Drawn in order (a later object hides an earlier one); at least one.
    occluders : sequence of OccluderSpec
        Drawn over every object, in order.
    size : (width, height)
        Frame size in pixels.
    fps : float
        Nominal frame rate (written to ``seqinfo.ini``).
    background : BGR triple
        Mean background colour (a dull, low-saturation green-grey by default).
    background_contrast : float
        Standard deviation (grey levels) of the smooth background texture.
    sensor_noise : float
        Standard deviation of per-pixel noise (triangular, nearly Gaussian) added to
        the whole frame every frame.
    name : str
        Sequence name.
    """

    def __init__(self, objects: Sequence[ObjectSpec], occluders: Sequence[OccluderSpec] = (), *,
                 size: tuple[int, int] = (320, 240), fps: float = 30.0,
                 background: tuple[int, int, int] = (104, 114, 100),
                 background_contrast: float = 14.0, sensor_noise: float = 2.0,
                 name: str = "synthetic"):
        self.objects = list(objects)
        self.occluders = list(occluders)
        if not self.objects:
            raise InputError("a scene needs at least one object")
        for o in self.objects:
            if not isinstance(o, ObjectSpec):
                raise InputError(f"objects must be ObjectSpec instances, got {type(o).__name__}")
        for o in self.occluders:
            if not isinstance(o, OccluderSpec):
                raise InputError(f"occluders must be OccluderSpec, got {type(o).__name__}")
        try:
            width, height = (int(v) for v in size)
        except (TypeError, ValueError):
            raise InputError(f"size must be (width, height), got {size!r}") from None
        if width <= 0 or height <= 0:
            raise InputError(f"size must be positive (width, height), got {size!r}")
        self.size = (width, height)
        self.fps = float(fps)
        if not math.isfinite(self.fps) or self.fps <= 0:
            raise InputError(f"fps must be > 0, got {fps!r}")
        self.background = _color("background colour", background)
        self.background_contrast = _nonneg("background_contrast", background_contrast)
        self.sensor_noise = _nonneg("sensor_noise", sensor_noise)
        self.name = str(name)

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def height(self) -> int:
        return self.size[1]

    def _check_obj(self, obj: int) -> ObjectSpec:
        if isinstance(obj, bool) or not isinstance(obj, (int, np.integer)) \
                or not 0 <= obj < len(self.objects):
            raise InputError(f"object index must be in [0, {len(self.objects)}), got {obj!r}")
        return self.objects[int(obj)]

    # -- geometry (no randomness) --------------------------------------------------

    def object_box(self, obj: int, frame: int) -> np.ndarray | None:
        """Top-left box of object ``obj`` (0-based index) at ``frame``; None if absent."""
        spec = self._check_obj(obj)
        return spec.box_at(frame) if spec.alive(frame) else None

    def _covers(self, obj: int, frame: int) -> list[tuple[float, float, float, float]]:
        covers = [_corners(o.box_at(frame)) for o in self.objects[obj + 1:] if o.alive(frame)]
        covers += [_corners(o.box_at(frame)) for o in self.occluders if o.alive(frame)]
        return covers

    def band_visibility(self, obj: int, frame: int, n_bands: int) -> np.ndarray:
        """Visible fraction ``(n_bands,)`` of each of ``n_bands`` equal horizontal bands
        of object ``obj``'s box at ``frame`` (top band first); zeros if it is absent."""
        spec = self._check_obj(obj)
        if isinstance(n_bands, bool) or not isinstance(n_bands, (int, np.integer)) \
                or n_bands < 1:
            raise InputError(f"n_bands must be a positive integer, got {n_bands!r}")
        out = np.zeros(int(n_bands))
        if not spec.alive(frame):
            return out
        x, y, w, h = (float(v) for v in spec.box_at(frame))
        covers = self._covers(obj, frame)
        edges = y + h * np.arange(n_bands + 1) / n_bands
        for k in range(n_bands):
            rect = (x, float(edges[k]), x + w, float(edges[k + 1]))
            area = (rect[2] - rect[0]) * (rect[3] - rect[1])
            out[k] = _visible_area(rect, covers, self.width, self.height) / area
        out[np.abs(out) < 1e-9] = 0.0  # exact 0 / 1 despite rounding in the corners
        out[np.abs(out - 1.0) < 1e-9] = 1.0
        return np.clip(out, 0.0, 1.0)

    def visibility(self, obj: int, frame: int) -> float:
        """Visible fraction of object ``obj``'s whole box at ``frame`` (0 if absent)."""
        return float(self.band_visibility(obj, frame, 1)[0])

    def ground_truth(self, n_frames: int) -> tuple[list[ObjectTruth], np.ndarray]:
        """Per-object truth over frames ``1..n_frames`` and visibility ``(n_objects,
        n_frames)``. An object is listed in a frame when it exists and its box overlaps
        the image (even if fully hidden)."""
        n = _check_n_frames(n_frames)
        vis = np.zeros((len(self.objects), n))
        truths = []
        for k, spec in enumerate(self.objects):
            frames, boxes, v = [], [], []
            for f in range(1, n + 1):
                if not spec.alive(f):
                    continue
                b = spec.box_at(f)
                in_image = _visible_area(_corners(b), [], self.width, self.height)
                if in_image <= 0:
                    continue
                vis[k, f - 1] = self.visibility(k, f)
                frames.append(f)
                boxes.append(b)
                v.append(vis[k, f - 1])
            truths.append(ObjectTruth(
                id=k + 1, frames=np.array(frames, dtype=int),
                boxes=np.array(boxes, dtype=float).reshape(-1, 4), visibility=np.array(v)))
        return truths, vis

    # -- rendering ---------------------------------------------------------------------

    def _background(self, rng: np.random.Generator) -> np.ndarray:
        H, W = self.height, self.width
        lum = _smooth_noise(rng, H, W, H // 40 + 2, W // 40 + 2, 1) \
            + 0.4 * _smooth_noise(rng, H, W, H // 10 + 2, W // 10 + 2, 1)
        tex = lum + 0.35 * _smooth_noise(rng, H, W, H // 60 + 2, W // 60 + 2, 3)
        tex = cv2.GaussianBlur(tex, (0, 0), 2.5).reshape(H, W, 3)  # no cubic-grid artefacts
        sd = float(tex.std())
        tex = tex / sd if sd > 0 else tex
        bg = np.asarray(self.background, dtype=np.float32) + self.background_contrast * tex
        return bg.astype(np.float32)

    def frames(self, rng: np.random.Generator | int, n_frames: int) -> Iterator[np.ndarray]:
        """Yield ``n_frames`` uint8 BGR frames ``(height, width, 3)``.

        The background and the textures are drawn from ``rng`` first, then each frame's
        pixel noise; the same generator state gives the same frames.
        """
        n = _check_n_frames(n_frames)
        rng = as_generator(rng)
        bg = self._background(rng)
        obj_tex = [_object_texture(rng, o) for o in self.objects]
        occ_tex = [_occluder_texture(rng, o) for o in self.occluders]
        obj_col = [np.asarray(o.colors, dtype=float) for o in self.objects]
        occ_col = [np.asarray([o.color], dtype=float) for o in self.occluders]
        for f in range(1, n + 1):
            img = bg.copy()
            for spec, tex, col in zip(self.objects, obj_tex, obj_col, strict=True):
                if spec.alive(f):
                    _draw(img, spec.box_at(f), col, tex, spec.noise, rng)
            for spec, tex, col in zip(self.occluders, occ_tex, occ_col, strict=True):
                if spec.alive(f):
                    _draw(img, spec.box_at(f), col, tex, spec.noise, rng)
            if self.sensor_noise > 0:
                img += _sensor_noise(rng, img.shape, self.sensor_noise)
            np.clip(img, 0.0, 255.0, out=img)
            yield np.rint(img, out=img).astype(np.uint8)

    def render(self, rng: np.random.Generator | int, n_frames: int) -> SyntheticSequence:
        """Render ``n_frames`` frames and their ground truth."""
        n = _check_n_frames(n_frames)
        frames = list(self.frames(rng, n))
        gt, vis = self.ground_truth(n)
        return SyntheticSequence(frames=frames, gt=gt, visibility=vis, fps=self.fps,
                                 scene=self, name=self.name)


# --------------------------------------------------------------------------- sequence


def _fmt(v: float) -> str:
    s = f"{float(v):.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _imwrite(path: Path, img: np.ndarray) -> None:
    if not cv2.imwrite(str(path), img, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
        raise OSError(f"could not write image {path}")


@dataclass(eq=False)
class SyntheticSequence:
    """Rendered frames with exact ground truth.

    Attributes
    ----------
    frames : list of ndarray (H, W, 3) uint8 BGR
        ``frames[f - 1]`` is frame ``f``.
    gt : list of ObjectTruth
        One per scene object, in scene order (``gt[k].id == k + 1``).
    visibility : ndarray (n_objects, n_frames)
        Visible fraction of each object's box (0 where absent).
    fps : float
    scene : Scene
        The geometry, for :meth:`band_visibility` and friends.
    name : str
    """

    frames: list[np.ndarray]
    gt: list[ObjectTruth]
    visibility: np.ndarray
    fps: float
    scene: Scene
    name: str = "synthetic"
    _band_cache: dict[tuple[int, int], np.ndarray] = field(default_factory=dict, repr=False,
                                                           init=False)

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def n_frames(self) -> int:
        return len(self.frames)

    @property
    def n_objects(self) -> int:
        return len(self.gt)

    @property
    def width(self) -> int:
        return self.scene.width

    @property
    def height(self) -> int:
        return self.scene.height

    def box(self, obj_index: int, frame: int) -> np.ndarray | None:
        """Ground-truth top-left box of an object at a 1-based frame, or None."""
        self.scene._check_obj(obj_index)
        t = self.gt[int(obj_index)]
        hit = np.flatnonzero(t.frames == frame)
        return t.boxes[hit[0]].copy() if hit.size else None

    def boxes_at(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """``(ids (M,), boxes (M, 4))`` of the objects in the image at ``frame``."""
        ids, boxes = [], []
        for t in self.gt:
            hit = np.flatnonzero(t.frames == frame)
            if hit.size:
                ids.append(t.id)
                boxes.append(t.boxes[hit[0]])
        return np.array(ids, dtype=int), np.array(boxes, dtype=float).reshape(-1, 4)

    def band_visibility(self, obj_index: int, n_bands: int) -> np.ndarray:
        """Visible fraction ``(n_frames, n_bands)`` of each horizontal band (top first)
        of an object's box per frame (zeros where the object is absent)."""
        key = (int(obj_index), int(n_bands))
        if key not in self._band_cache:
            self._band_cache[key] = np.stack([
                self.scene.band_visibility(obj_index, f, n_bands)
                for f in range(1, self.n_frames + 1)])
        return self._band_cache[key].copy()

    def detections(self, rng: np.random.Generator | int, *, p_detect: float = 0.9,
                   sigma: float = 2.0, clutter_rate: float = 1.0,
                   min_visibility: float = 0.3) -> np.ndarray:
        """Noisy detections ``(N, 7)``: ``frame, x, y, w, h, score, id`` (0-based boxes;
        ``id`` is the true object id or -1 for clutter), sorted by frame.

        Each object whose visible fraction is at least ``min_visibility`` is detected
        with probability ``p_detect``; its box gets independent Gaussian noise of
        standard deviation ``sigma`` pixels on x, y, w, h (w, h kept >= 2) and a score
        in [0.5, 1). Each frame also gets Poisson(``clutter_rate``) clutter boxes, placed
        uniformly inside the image with sizes like the objects', scores in [0, 0.6).
        """
        rng = as_generator(rng)
        if not 0.0 <= p_detect <= 1.0:
            raise InputError(f"p_detect must be in [0, 1], got {p_detect!r}")
        sigma = _nonneg("sigma", sigma)
        clutter_rate = _nonneg("clutter_rate", clutter_rate)
        sizes = np.concatenate([t.boxes[:, 2:] for t in self.gt])
        if sizes.size == 0:
            sizes = np.array([[0.1 * self.width, 0.2 * self.height]])
        rows: list[list[float]] = []
        for f in range(1, self.n_frames + 1):
            ids, boxes = self.boxes_at(f)
            for i, b in zip(ids, boxes, strict=True):
                if self.visibility[i - 1, f - 1] < min_visibility:
                    continue
                if rng.random() >= p_detect:
                    continue
                nb = b + sigma * rng.standard_normal(4)
                nb[2:] = np.maximum(nb[2:], 2.0)
                rows.append([f, *nb, rng.uniform(0.5, 1.0), i])
            for _ in range(int(rng.poisson(clutter_rate))):
                w, h = sizes[rng.integers(len(sizes))] * rng.uniform(0.8, 1.2)
                w, h = min(w, self.width), min(h, self.height)
                x = rng.uniform(0.0, self.width - w)
                y = rng.uniform(0.0, self.height - h)
                rows.append([f, x, y, w, h, rng.uniform(0.0, 0.6), -1])
        return np.array(rows, dtype=float).reshape(-1, 7)

    def write_otb(self, folder: str | Path, obj_index: int = 0) -> Path:
        """Write an OTB layout: ``img/%04d.png`` and ``groundtruth_rect.txt`` (one
        ``x,y,w,h`` line per frame, 1-based top-left; ``NaN,NaN,NaN,NaN`` where the
        object is not in the image). Returns the folder."""
        self.scene._check_obj(obj_index)
        folder = Path(folder)
        (folder / "img").mkdir(parents=True, exist_ok=True)
        for f, img in enumerate(self.frames, start=1):
            _imwrite(folder / "img" / f"{f:04d}.png", img)
        lines = []
        for f in range(1, self.n_frames + 1):
            b = self.box(obj_index, f)
            if b is None:
                lines.append("NaN,NaN,NaN,NaN")
            else:
                lines.append(",".join(_fmt(v) for v in (b[0] + 1, b[1] + 1, b[2], b[3])))
        (folder / "groundtruth_rect.txt").write_text("\n".join(lines) + "\n")
        return folder

    def write_mot(self, folder: str | Path, rng: np.random.Generator | int = 0, *,
                  p_detect: float = 0.9, sigma: float = 2.0, clutter_rate: float = 1.0,
                  min_visibility: float = 0.3) -> Path:
        """Write a MOTChallenge layout: ``seqinfo.ini``, ``img1/%06d.png``,
        ``gt/gt.txt`` (``frame,id,x,y,w,h,1,-1,-1,-1``, 1-based, every frame an object
        is in the image) and ``det/det.txt`` (``frame,-1,x,y,w,h,score,-1,-1,-1``) from
        :meth:`detections` with ``rng``. Returns the folder."""
        folder = Path(folder)
        dets = self.detections(rng, p_detect=p_detect, sigma=sigma,
                               clutter_rate=clutter_rate, min_visibility=min_visibility)
        for sub in ("img1", "gt", "det"):
            (folder / sub).mkdir(parents=True, exist_ok=True)
        (folder / "seqinfo.ini").write_text(
            "[Sequence]\n"
            f"name={self.name}\nimDir=img1\nframeRate={_fmt(self.fps)}\n"
            f"seqLength={self.n_frames}\nimWidth={self.width}\nimHeight={self.height}\n"
            "imExt=.png\n")
        for f, img in enumerate(self.frames, start=1):
            _imwrite(folder / "img1" / f"{f:06d}.png", img)
        gt_rows = []
        for t in self.gt:
            for f, b in zip(t.frames, t.boxes, strict=True):
                gt_rows.append((int(f), t.id, b))
        gt_rows.sort(key=lambda r: (r[0], r[1]))
        (folder / "gt" / "gt.txt").write_text("".join(
            f"{f},{i},{_fmt(b[0] + 1)},{_fmt(b[1] + 1)},{_fmt(b[2])},{_fmt(b[3])},1,-1,-1,-1\n"
            for f, i, b in gt_rows))
        (folder / "det" / "det.txt").write_text("".join(
            f"{int(d[0])},-1,{_fmt(d[1] + 1)},{_fmt(d[2] + 1)},{_fmt(d[3])},{_fmt(d[4])},"
            f"{_fmt(d[5])},-1,-1,-1\n" for d in dets))
        return folder


# --------------------------------------------------------------------------- presets


def demo_scene(seed: int | np.random.Generator = 0, n_frames: int = 90) -> SyntheticSequence:
    """A person walking behind a low wall, plus a distractor (default input of ``pgm demo``).

    320x240, 30 fps. Object 0 (the target, "person"): a 30x80 box, red top band over
    blue bottom band, starting at top-left (20, 100) — top band rows [100, 140), bottom
    band rows [140, 180) in every frame — walking right at 2.6 px/frame with a
    horizontal gait wobble of 3 px (period 30 frames): ``x = 20 + 2.6 t + 3 sin(2 pi
    t / 30)``, ``t = frame - 1`` (x = 251.4 at frame 90). Occluder: a static magazine
    at (140, 140, 90, 60), columns [140, 230), rows [140, 200): its top edge is exactly
    the boundary between the bands, so the top band is fully visible in every frame.
    The lower band is partly hidden in frames 35-47, fully hidden (visibility 0) in
    frames 48-69 (22 frames) and partly hidden in frames 70-82. Object 1 (distractor):
    a 26x64 orange-over-green box at (270, 24) moving left at 1.6 px/frame with a 2 px
    vertical wobble (period 24); it never overlaps the target or the occluder.
    """
    person = ObjectSpec(box=(20, 100, 30, 80), colors=(_RED, _BLUE), velocity=(2.6, 0.0),
                        wobble=(3.0, 0.0), wobble_period=30.0, name="person")
    distractor = ObjectSpec(box=(270, 24, 26, 64), colors=((30, 160, 235), (50, 120, 40)),
                            velocity=(-1.6, 0.0), wobble=(0.0, 2.0), wobble_period=24.0,
                            name="distractor")
    wall = OccluderSpec(box=(140, 140, 90, 60))
    scene = Scene([person, distractor], [wall], size=(320, 240), fps=30.0, name="demo")
    return scene.render(as_generator(seed), n_frames)


def part_occlusion_scene(seed: int | np.random.Generator = 0, n_frames: int = 80,
                         n_bands: int = 2, hidden_band: int | Sequence[int] | None = None,
                         colors: Sequence[tuple[int, int, int]] | None = None
                         ) -> SyntheticSequence:
    """One banded object; an occluder hides exactly the chosen band(s) for a while.

    320x240, 30 fps. The object is 40 px wide with ``n_bands`` bands 30 px high each
    (height ``30 n_bands``), vertically centred: top ``y = (240 - 30 n_bands) / 2``
    (90 for two bands, 75 for three), band ``k`` on rows ``[y + 30k, y + 30(k+1))``.
    It moves right at 2.5 px/frame with no vertical motion: ``x = 20 + 2.5 t``,
    ``t = frame - 1``. Default colours: red over blue (2 bands), red / green / blue (3).

    ``hidden_band`` (default: the bottom band; an int or a sequence of band indices,
    0 = top) is covered by one static magazine occluder per contiguous run of hidden
    bands, columns [100, 200) (100 px wide), rows exactly those of the run (extended
    10 px beyond the object if the run touches its top or bottom edge). The hidden
    band(s) are therefore partly hidden in frames 18-32 (the object enters), fully
    hidden (visibility exactly 0) in frames 33-57 (25 frames; object x in [100, 160]),
    partly hidden in frames 58-72, and the object is fully visible again from frame 73
    (x >= 200; x = 217.5 at frame 80). The other bands have visibility 1 in every
    frame. Frames 1-17 are unoccluded (for initialisation).
    """
    if isinstance(n_bands, bool) or not isinstance(n_bands, (int, np.integer)) or n_bands < 1:
        raise InputError(f"n_bands must be a positive integer, got {n_bands!r}")
    n_bands = int(n_bands)
    if hidden_band is None:
        hidden = [n_bands - 1]
    elif isinstance(hidden_band, (int, np.integer)) and not isinstance(hidden_band, bool):
        hidden = [int(hidden_band)]
    else:
        hidden = sorted({int(b) for b in hidden_band})
    if not hidden or any(not 0 <= b < n_bands for b in hidden):
        raise InputError(f"hidden_band must name bands in [0, {n_bands}), got {hidden_band!r}")
    if colors is None:
        palette = {1: (_RED,), 2: (_RED, _BLUE), 3: (_RED, _GREEN, _BLUE)}
        if n_bands not in palette:
            hsv = np.array([[[int(180 * k / n_bands), 220, 200] for k in range(n_bands)]],
                           dtype=np.uint8)
            colors = [tuple(int(v) for v in c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0]]
        else:
            colors = palette[n_bands]
    colors = list(colors)
    if len(colors) != n_bands:
        raise InputError(f"colors must hold {n_bands} band colours, got {len(colors)}")
    band_h, w = 30.0, 40.0
    h = band_h * n_bands
    y = (240.0 - h) / 2.0
    obj = ObjectSpec(box=(20.0, y, w, h), colors=colors, velocity=(2.5, 0.0), name="object")
    edges = y + h * np.arange(n_bands + 1) / n_bands  # same arithmetic as band_visibility
    runs: list[list[int]] = []
    for b in hidden:
        if runs and runs[-1][-1] == b - 1:
            runs[-1].append(b)
        else:
            runs.append([b])
    occluders = []
    for run in runs:
        top = float(edges[run[0]]) if run[0] > 0 else y - 10.0
        bottom = float(edges[run[-1] + 1]) if run[-1] < n_bands - 1 else y + h + 10.0
        occluders.append(OccluderSpec(box=(100.0, top, 100.0, bottom - top)))
    scene = Scene([obj], occluders, size=(320, 240), fps=30.0,
                  name=f"part-occlusion-{n_bands}")
    return scene.render(as_generator(seed), n_frames)


_MULTI_OBJECTS = (
    # (box, colours, velocity, wobble, scale, start, end)
    ((20, 200, 32, 84), (_RED, _BLUE), (3.0, 0.3), (0.0, 2.0), 1.0, 1, None),
    ((600, 190, 30, 76), ((40, 200, 220), (150, 50, 130)), (-4.5, 0.4), (0.0, 0.0), 1.0, 1, 90),
    ((250, -80, 28, 72), (_GREEN, (20, 120, 240)), (0.3, 4.0), (0.0, 0.0), 1.0, 10, None),
    ((80, 380, 40, 60), ((200, 200, 40), (40, 40, 160), (60, 140, 60)), (2.0, -1.0),
     (2.0, 0.0), 1.0, 30, 85),
    ((520, 40, 26, 70), ((180, 100, 240), (50, 100, 30)), (-1.5, 2.0), (0.0, 0.0), 1.004,
     45, None),
    ((-34, 360, 34, 90), ((0, 140, 255), (120, 60, 20)), (5.0, -0.3), (0.0, 0.0), 1.0, 20,
     None),
)


def multi_target_scene(seed: int | np.random.Generator = 0, n_frames: int = 100,
                       n_objects: int = 6, occluder: bool = True) -> SyntheticSequence:
    """Several objects with births, deaths and crossings in a 640x480 frame (30 fps).

    The first ``n_objects`` (1..6) of this fixed layout (object ``k`` has MOT id
    ``k + 1``; ``t = frame - start``; later objects are drawn in front):

    ====  ======================  ========================  ===========  ==============
    id    box at start (x,y,w,h)  velocity (px/frame)       frames       colours (top..)
    ====  ======================  ========================  ===========  ==============
    1     (20, 200, 32, 84)       (3.0, 0.3), y-wobble 2    1-end        red / blue
    2     (600, 190, 30, 76)      (-4.5, 0.4)               1-89, dies   yellow / purple
    3     (250, -80, 28, 72)      (0.3, 4.0), from the top  13-end       green / orange
    4     (80, 380, 40, 60)       (2.0, -1.0), x-wobble 2   30-84, dies  cyan/red/green
    5     (520, 40, 26, 70)       (-1.5, 2.0), x1.004/frame 45-end       pink / green
    6     (-34, 360, 34, 90)      (5.0, -0.3), from left    21-end       orange / navy
    ====  ======================  ========================  ===========  ==============

    ("frames" lists the frames where the box overlaps the image; object 3 is born at
    frame 10 above the image, object 6 at frame 20 left of it.) Wobble periods are 28
    frames. Overlaps with the default 100 frames: 1 & 2 in frames 75-82 (crossing),
    1 & 3 in 74-95 and 2 & 3 in 69-80 (3 walks down through them), 4 & 6 in 41-65
    (6 overtakes 4, in front of it). With ``occluder=True`` a static magazine at
    (400, 250, 70, 110) hides the lower part of object 2 in frames 30-52. Use
    :meth:`SyntheticSequence.write_mot` or :meth:`SyntheticSequence.detections` for
    noisy detections with clutter.
    """
    if isinstance(n_objects, bool) or not isinstance(n_objects, (int, np.integer)) \
            or not 1 <= n_objects <= len(_MULTI_OBJECTS):
        raise InputError(f"n_objects must be in [1, {len(_MULTI_OBJECTS)}], got {n_objects!r}")
    objects = [
        ObjectSpec(box=box, colors=cols, velocity=vel, wobble=wob, wobble_period=28.0,
                   scale=sc, start=s, end=e, name=f"target-{k + 1}")
        for k, (box, cols, vel, wob, sc, s, e) in enumerate(_MULTI_OBJECTS[:n_objects])
    ]
    occ = [OccluderSpec(box=(400, 250, 70, 110))] if occluder else []
    scene = Scene(objects, occ, size=(640, 480), fps=30.0, name="multi-target")
    return scene.render(as_generator(seed), n_frames)
