"""Issue 26, item 11: ``auto`` camera motion finds a still camera cheaply (it estimates a
frame only when its verdict can change a result) and reports what estimating every frame
reports: checked against that reference on a still camera, a moving one, one that starts
moving and one that stops — exactly where every frame's corners are found anew, and, where
corners are followed from frame to frame (the default), the same verdicts with motions
within the tracking's sub-pixel differences."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pgm.observation.camera_motion import CameraMotionEstimator


def _reference(frames, *, min_shift=1.0, window=20, min_fraction=0.8, **settings):
    """``auto`` as specified: every frame estimated (an ``"on"`` estimator with the same
    settings), a motion reported when it moves some image corner by ``min_shift`` and so
    did ``min_fraction`` of the window."""
    every = CameraMotionEstimator("on", **settings)
    out, recent = [], []
    for img in frames:
        h, w = img.shape[:2]
        A = every(img)
        if len(out) == 0:
            out.append(None)
            continue
        moved = A is not None and CameraMotionEstimator.corner_shift(A, w, h) >= min_shift
        recent = (recent + [moved])[-window:]
        out.append(A if moved and sum(recent) >= min_fraction * window else None)
    return out


def _video(pan, n=60, h=240, w=320, seed=0):
    """Frames of a textured scene seen through a camera panning ``pan(k)`` px at frame
    ``k``, with a small object walking across and sensor noise."""
    rng = np.random.default_rng(seed)
    big = rng.uniform(0, 255, (h // 6 + 40, w // 6 + 60)).astype(np.float32)
    big = cv2.resize(big, ((w // 6 + 60) * 6, (h // 6 + 40) * 6), interpolation=cv2.INTER_CUBIC)
    big = cv2.GaussianBlur(np.clip(big, 0, 255), (0, 0), 1.2)
    frames, x = [], 0.0
    for k in range(n):
        x += pan(k)
        m = np.float32([[1, 0, -(60 + x)], [0, 1, -60]])
        img = cv2.warpAffine(big, m, (w, h), flags=cv2.INTER_LINEAR)
        cv2.rectangle(img, (20 + 3 * k, 100), (40 + 3 * k, 150), 40.0, -1)
        img = img + rng.normal(0, 1.5, img.shape)
        frames.append(cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
    return frames


CAMERAS = {"still": lambda k: 0.0, "moving": lambda k: 2.5,
           "starts moving": lambda k: 2.5 if k >= 25 else 0.0,
           "stops": lambda k: 2.5 if k < 30 else 0.0,
           "moves twice": lambda k: 2.5 if (10 <= k < 32 or k >= 45) else 0.0}


@pytest.mark.parametrize("track", [False, True], ids=["corners anew", "corners followed"])
@pytest.mark.parametrize("camera", CAMERAS, ids=list(CAMERAS))
def test_auto_reports_what_estimating_every_frame_reports(camera, track):
    frames = _video(CAMERAS[camera])
    est = CameraMotionEstimator("auto", track=track)
    got = [est(f) for f in frames]
    want = _reference(frames, track=track)
    assert [a is None for a in got] == [a is None for a in want]
    for a, b in zip(got, want, strict=True):
        if a is not None and not track:
            np.testing.assert_array_equal(a, b)
        elif a is not None:  # followed corners differ where auto skipped frames
            np.testing.assert_allclose(a, b, atol=0.05)
    assert est.frames_moved == sum(a is not None for a in want)
    if camera != "still":
        assert est.frames_moved > 0  # the scene does exercise reporting


def test_a_still_camera_is_estimated_on_a_quarter_of_its_frames():
    frames = _video(CAMERAS["still"], n=80)
    est = CameraMotionEstimator("auto")
    for f in frames:
        assert est(f) is None
    # 5 frames in every 20 must be known not to have moved (20 - 16 + 1)
    assert est.frames_estimated <= 0.3 * len(frames)


def test_on_mode_estimates_every_frame():
    frames = _video(CAMERAS["moving"], n=8)
    est = CameraMotionEstimator("on")
    got = [est(f) for f in frames]
    assert got[0] is None and all(a is not None for a in got[1:])
    assert est.frames_estimated == len(frames) - 1
