"""Preset scenes: the demo's walker behind a magazine, a part-occlusion scene and a
multi-target scene with births, deaths and crossings."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.core.rng import as_generator
from pgm.synthetic._checks import _check_n_frames
from pgm.synthetic.scene import (
    _BLUE,
    _GREEN,
    _RED,
    ObjectSpec,
    OccluderSpec,
    Scene,
    _sensor_noise,
    _smooth_noise,
)
from pgm.synthetic.sequence import SyntheticSequence

__all__ = ["demo_scene", "part_occlusion_scene", "multi_target_scene", "jump_scene",
           "JumpSequence", "desk_scene", "DeskSequence"]


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

    ==  ======================  =========================  ===========  ===============
    id  box at start (x,y,w,h)  velocity (px/frame)        frames       colours (top..)
    ==  ======================  =========================  ===========  ===============
    1   (20, 200, 32, 84)       (3.0, 0.3), y-wobble 2     1-end        red / blue
    2   (600, 190, 30, 76)      (-4.5, 0.4)                1-89, dies   yellow / purple
    3   (250, -80, 28, 72)      (0.3, 4.0), from the top   13-end       green / orange
    4   (80, 380, 40, 60)       (2.0, -1.0), x-wobble 2    30-84, dies  cyan/red/green
    5   (520, 40, 26, 70)       (-1.5, 2.0), x1.004/frame  45-end       pink / green
    6   (-34, 360, 34, 90)      (5.0, -0.3), from left     21-end       orange / navy
    ==  ======================  =========================  ===========  ===============

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


class JumpSequence(NamedTuple):
    """Frames of :func:`jump_scene`: ``frames`` (list of (H, W, 3) uint8 BGR, frame
    ``k + 1`` at index ``k``), ``boxes`` (n, 4) top-left ``(x, y, w, h)`` of the object
    (also where it is hidden), ``visible`` (n,) whether any of it is in view."""

    frames: list
    boxes: np.ndarray
    visible: np.ndarray


def jump_scene(seed: int | np.random.Generator = 0, n_frames: int = 90) -> JumpSequence:
    """A textured object that vanishes behind an occluder and comes back across the frame.

    320x240 grey-textured background. The object (40x48, its own fixed texture) starts
    centred at (70, 120) and moves right 0.8 px/frame with a 3 px vertical wobble (period
    40 frames); in frame 36 a grey page covers it
    (70x80 at its last position, for the rest of the sequence) and the object is hidden
    for 20 frames (36-55); from frame 56 it is in view again centred at (250, 110), 180
    px to the right, moving left 0.5 px/frame. A tracker that stays where the object
    vanished has lost it; one that re-detects finds it again from frame 56.
    """
    rng = as_generator(seed)
    n_frames = _check_n_frames(n_frames)
    H, W = 240, 320
    bg = 120.0 + 22.0 * _smooth_noise(rng, H, W, 14, 18, 1)[..., 0]
    ow, oh = 40, 48
    tex = (_smooth_noise(rng, oh, ow, 5, 4, 1) + 0.5 * _smooth_noise(rng, oh, ow, 12, 10, 1))
    obj = np.clip(128.0 + 40.0 * tex[..., 0] / max(float(tex.std()), 1e-6), 0, 255)
    page = 200.0 + 6.0 * _smooth_noise(rng, 80, 70, 8, 7, 1)[..., 0]
    t = np.arange(1, n_frames + 1, dtype=float)
    cx = np.where(t <= 55, 70.0 + 0.8 * (np.minimum(t, 35) - 1), 250.0 - 0.5 * (t - 56))
    cy = np.where(t <= 55, 120.0 + 3.0 * np.sin(2 * np.pi * (t - 1) / 40), 110.0)
    boxes = np.stack([cx - ow / 2, cy - oh / 2, np.full_like(cx, ow), np.full_like(cx, oh)],
                     axis=1)
    visible = (t <= 35) | (t >= 56)
    px, py = int(round(cx[min(34, n_frames - 1)] - 35)), int(round(cy[min(34, n_frames - 1)] - 40))
    frames = []
    for k in range(n_frames):
        img = bg.copy()
        if visible[k]:
            x0, y0 = int(round(boxes[k, 0])), int(round(boxes[k, 1]))
            img[y0:y0 + oh, x0:x0 + ow] = obj
        if t[k] >= 36:
            img[py:py + 80, px:px + 70] = page
        img = np.clip(img + _sensor_noise(rng, img.shape, 4.0), 0, 255).astype(np.uint8)
        frames.append(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
    return JumpSequence(frames, boxes, visible)


class DeskSequence(NamedTuple):
    """Frames of :func:`desk_scene`: ``frames`` (list of (H, W, 3) uint8 BGR, grey
    content; frame ``k + 1`` at index ``k``) and ``boxes`` (n, 4) top-left
    ``(x, y, w, h)``, the bounding box of the cube's visible faces."""

    frames: list
    boxes: np.ndarray


def _wander(rng: np.random.Generator, n: int, sd: float, width: float) -> np.ndarray:
    """A smooth random signal of standard deviation ``sd`` (in expectation, whatever
    ``n``): white noise under a Gaussian kernel of ``width`` frames."""
    half = int(3 * width)
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / width) ** 2)
    k /= k.sum()
    y = np.convolve(rng.standard_normal(n + 2 * half), k, mode="valid")
    return sd * y / math.sqrt(float(np.sum(k * k)))


#: the cube's corners (x, y, z in {-1, 1}) and its faces: corner indices (bits x y z)
#: counter-clockwise from outside, and the outward normal
_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
_FACES = (((4, 6, 7, 5), (1, 0, 0)), ((0, 1, 3, 2), (-1, 0, 0)), ((2, 3, 7, 6), (0, 1, 0)),
          ((0, 4, 5, 1), (0, -1, 0)), ((1, 5, 7, 3), (0, 0, 1)), ((0, 2, 6, 4), (0, 0, -1)))


def _rotation(yaw: float, pitch: float, roll: float) -> np.ndarray:
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    return rz @ rx @ ry


def desk_scene(seed: int | np.random.Generator = 0, n_frames: int = 1344, *,
               background: float = 0.3, size: float = 44.0) -> DeskSequence:
    """A long single-object video: a textured cube turned by hand under a desk lamp.

    320x240 grey, as the kind of sequence a blind test of issue 25 used (a small object
    moved by hand under a lamp: lighting changes, in- and out-of-plane rotation, scale
    change). The cube (a face about ``size`` px across, six textures) wanders over the
    frame (smooth random position, 55 x 35 px standard deviation before a soft bound
    that keeps it in view), towards and away from the camera
    (log-distance 0.18 sd) and turns about all three axes (0.7, 0.35, 0.35 rad sd), each
    face lit by its angle to a lamp whose direction, brightness (15 % sd) and pool of
    light move slowly. ``background`` scales the desk's texture: at 1 it is as strong as
    the cube's (a correlation filter's context then learns the static desk: see
    ``docs/results.md``), at the default 0.3 it is plainer. The ground truth is the
    bounding box of the visible faces.
    """
    rng = as_generator(seed)
    n_frames = _check_n_frames(n_frames)
    H, W, T, f = 240, 320, 64, 400.0
    desk = 110.0 + background * (30.0 * _smooth_noise(rng, H, W, 10, 12, 1)[..., 0]
                                 + 12.0 * _smooth_noise(rng, H, W, 40, 50, 1)[..., 0])
    textures = []
    for _ in _FACES:
        t = (_smooth_noise(rng, T, T, 4, 4, 1)[..., 0]
             + 0.6 * _smooth_noise(rng, T, T, 12, 12, 1)[..., 0])
        textures.append(np.clip(140 + 45 * t / t.std(), 0, 255).astype(np.float32))
    n = n_frames
    # each signal from its own stream, so a shorter video is the start of a longer one
    walk = iter(rng.spawn(12))
    # held inside the frame: a soft bound (tanh) a cube's width from the borders
    mx, my = W / 2 - 1.2 * size, H / 2 - 1.2 * size
    cx = W / 2 + mx * np.tanh(_wander(next(walk), n, 55, 25) / mx)
    cy = H / 2 + my * np.tanh(_wander(next(walk), n, 35, 25) / my)
    depth = np.exp(_wander(next(walk), n, 0.18, 60))
    yaw = _wander(next(walk), n, 0.7, 40) + 0.3
    pitch = _wander(next(walk), n, 0.35, 40) + 0.3
    roll = _wander(next(walk), n, 0.35, 40)
    lamp = 1.0 + _wander(next(walk), n, 0.15, 80)
    light = np.stack([_wander(next(walk), n, 0.5, 80), _wander(next(walk), n, 0.5, 80) - 0.6,
                      -np.ones(n)], 1)
    light /= np.linalg.norm(light, axis=1, keepdims=True)
    lx = W / 2 + _wander(next(walk), n, 60, 100)
    ly = H / 2 + _wander(next(walk), n, 40, 100)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    src = np.array([[0, 0], [T, 0], [T, T], [0, T]], np.float32)
    distance = f / (size / 2 / math.sqrt(3) * 1.4)
    frames, boxes = [], []
    for k in range(n):
        rot = _rotation(yaw[k], pitch[k], roll[k])
        corners = _CUBE @ rot.T + np.array([0.0, 0.0, distance * depth[k]])
        uv = np.stack([cx[k] + f * corners[:, 0] / corners[:, 2],
                       cy[k] + f * corners[:, 1] / corners[:, 2]], 1)
        pool = (0.75 + 0.5 * np.exp(-((xx - lx[k]) ** 2 + (yy - ly[k]) ** 2)
                                    / (2 * 120.0 ** 2)))
        img = desk.copy()
        seen = []
        for tex, (idx, normal) in zip(textures, _FACES, strict=True):
            nw = rot @ np.array(normal, float)
            if nw @ corners[list(idx)].mean(axis=0) >= 0:  # facing away
                continue
            shade = 0.45 + 0.75 * max(0.0, -float(nw @ light[k]))
            hom = cv2.getPerspectiveTransform(src, uv[list(idx)].astype(np.float32))
            face = cv2.warpPerspective(tex * shade, hom, (W, H), flags=cv2.INTER_LINEAR)
            mask = cv2.warpPerspective(np.ones((T, T), np.float32), hom, (W, H),
                                       flags=cv2.INTER_LINEAR)
            img = img * (1 - mask) + face * mask
            seen.append(uv[list(idx)])
        pts = np.concatenate(seen)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        boxes.append([lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1]])
        img = img * (lamp[k] * pool) + _sensor_noise(rng, img.shape, 3.0)
        frames.append(cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    return DeskSequence(frames, np.asarray(boxes))
