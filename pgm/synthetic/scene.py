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
from dataclasses import dataclass

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.core.rng import as_generator
from pgm.synthetic._checks import _box, _check_n_frames, _color, _finite, _frame_range, _nonneg
from pgm.synthetic.sequence import ObjectTruth, SyntheticSequence

__all__ = ["ObjectSpec", "OccluderSpec", "ObjectTruth", "Scene", "MAGAZINE_COLOR"]

#: Default occluder page colour (BGR): a light, unsaturated grey, far from band colours.
MAGAZINE_COLOR: tuple[int, int, int] = (178, 182, 186)

_RED = (40, 40, 200)
_BLUE = (190, 90, 30)
_GREEN = (60, 170, 50)


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
