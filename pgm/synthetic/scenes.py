"""Preset scenes: the demo's walker behind a magazine, a part-occlusion scene and a
multi-target scene with births, deaths and crossings."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.core.rng import as_generator
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
           "JumpSequence"]


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
    if n_frames < 1:
        raise InputError(f"n_frames must be positive, got {n_frames}")
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
