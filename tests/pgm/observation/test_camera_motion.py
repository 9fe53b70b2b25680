"""Camera motion: a known synthetic camera motion is recovered; states follow it."""

import cv2
import numpy as np
import pytest

from pgm import FactorGraph, FrameContext, Variable
from pgm.core.motion import motion_scale, warp_states
from pgm.factors import GaussianPrior, LinearGaussianTransition
from pgm.inference import Engine
from pgm.observation.camera_motion import CameraMotionEstimator, track_camera_motion


def _scene(rng, h=360, w=480):
    """A textured background: blurred noise at two scales (plenty of corners)."""
    img = rng.uniform(0, 255, (h // 8, w // 8)).astype(np.float32)
    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC)
    img += rng.normal(0, 25, (h, w)).astype(np.float32)
    img = cv2.GaussianBlur(img, (0, 0), 1.5)
    return cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)


def _similarity(angle_deg, scale, tx, ty, centre):
    A = cv2.getRotationMatrix2D(centre, angle_deg, scale)
    A[:, 2] += (tx, ty)
    return A


@pytest.mark.parametrize("flow_epsilon", [None, 0.01])
@pytest.mark.parametrize("angle, scale, tx, ty", [(0.0, 1.0, 6.3, -2.7),
                                                  (1.0, 1.02, -4.0, 3.5)])
def test_estimator_recovers_a_known_camera_motion(angle, scale, tx, ty, flow_epsilon):
    """Within a quarter pixel at the image's corners, with the default Lucas–Kanade
    stopping rule and with OpenCV's own (0.01 px)."""
    rng = np.random.default_rng(0)
    big = _scene(rng, 480, 640)
    h, w = 360, 480
    frame0 = big[60:60 + h, 80:80 + w]
    A_true = _similarity(angle, scale, tx, ty, (w / 2, h / 2))
    # the new frame sees the big scene through the motion (so the borders stay filled)
    full = np.hstack([A_true[:, :2], (A_true[:, :2] @ [-80, -60] + A_true[:, 2])[:, None]])
    frame1 = cv2.warpAffine(big, full, (w, h), flags=cv2.INTER_LINEAR)
    est = CameraMotionEstimator("on", **({} if flow_epsilon is None
                                         else {"flow_epsilon": flow_epsilon}))
    assert est(frame0) is None
    A = est(frame1)
    corners = np.array([[0, 0], [w, 0], [0, h], [w, h]], dtype=float)
    err = np.linalg.norm((corners @ A[:, :2].T + A[:, 2]) - (corners @ A_true[:, :2].T
                                                            + A_true[:, 2]), axis=1)
    assert err.max() < 0.25, (A, A_true)


def test_auto_mode_reports_no_motion_for_a_still_camera():
    rng = np.random.default_rng(1)
    img = _scene(rng)
    noisy = np.clip(img.astype(int) + rng.integers(-2, 3, img.shape), 0, 255).astype(np.uint8)
    est = CameraMotionEstimator("auto")
    assert est(img) is None and est(noisy) is None and est.frames_moved == 0
    assert CameraMotionEstimator("off")(img) is None
    with pytest.raises(ValueError, match="mode"):
        CameraMotionEstimator("sometimes")
    for bad in (0.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="flow_epsilon"):
            CameraMotionEstimator("on", flow_epsilon=bad)
        with pytest.raises(ValueError, match="flow_epsilon"):
            track_camera_motion(img[..., 0], img[..., 0], None, flow_epsilon=bad)


def test_warp_states_moves_positions_velocities_and_sizes():
    A = np.array([[0.0, -2.0, 10.0], [2.0, 0.0, -5.0]])  # 90 degrees, scale 2, shift
    x = np.array([[1.0, 3.0, 4.0, 8.0]])
    out = warp_states(x, ("cx", "cy", "w", "h"), A)
    np.testing.assert_allclose(out, [[10.0 - 6.0, -5.0 + 2.0, 8.0, 16.0]])
    s = warp_states(np.array([[1.0, 0.5, 3.0, -1.0]]), ("px", "vx", "py", "vy"), A)
    np.testing.assert_allclose(s, [[4.0, 2.0, -3.0, 1.0]])
    assert motion_scale(A) == pytest.approx(2.0)
    assert warp_states(x, ("a", "b", "c", "d"), A) is x  # no position labels: untouched


def test_prediction_follows_the_camera():
    """With no process noise the predicted particles are exactly the warped ones."""
    g = FactorGraph([Variable("p", 4, labels=("px", "vx", "py", "vy"))],
                    [GaussianPrior("p", mean=[50.0, 1.0, 20.0, 0.0], cov=4.0),
                     LinearGaussianTransition("p", F=np.eye(4), Q=0.0)])
    A = np.array([[1.0, 0.0, 7.0], [0.0, 1.0, -3.0]])
    eng = Engine(g, np.random.default_rng(0), num_particles=20)
    x0 = eng.step(FrameContext(1)).beliefs["p"].x
    x1 = eng.step(FrameContext(2, camera_motion=A)).beliefs["p"].x
    np.testing.assert_allclose(x1, warp_states(x0, ("px", "vx", "py", "vy"), A))


def test_auto_mode_compensates_a_camera_that_keeps_moving():
    """A camera panning 3 px per frame: after 16 of 20 moving frames, auto reports it."""
    rng = np.random.default_rng(2)
    big = _scene(rng, 360, 900)
    est = CameraMotionEstimator("auto")
    got = [est(big[:, 3 * k:3 * k + 480]) for k in range(30)]  # the view slides right
    assert all(a is None for a in got[:16])
    assert all(a is not None for a in got[16:]) and est.frames_moved == 14
    np.testing.assert_allclose(got[-1][:, 2], [-3.0, 0.0], atol=0.15)


def test_a_1080p_camera_is_estimated_on_a_halved_frame_with_followed_corners(monkeypatch):
    """Issue 39: a 1920x1080 frame is analysed at 480x270 (two halvings), its corners are
    followed from frame to frame (found anew only when fewer than half remain), and a
    known pan and zoom is recovered within half a full-resolution pixel at the corners."""
    import pgm.observation.camera_motion as cm

    rng = np.random.default_rng(3)
    big = _scene(rng, 1300, 2300)
    h, w = 1080, 1920
    found = []
    real = cv2.goodFeaturesToTrack
    monkeypatch.setattr(cm.cv2, "goodFeaturesToTrack",
                        lambda img, **kw: found.append(img.shape) or real(img, **kw))
    est = CameraMotionEstimator("on")
    errs, A_prev = [], np.eye(2, 3)
    for k in range(6):
        A_true = _similarity(0.1 * k, 1.0 + 0.003 * k, -7.0 * k, 2.0 * k, (w / 2, h / 2))
        full = np.hstack([A_true[:, :2],
                          (A_true[:, :2] @ [-150, -100] + A_true[:, 2])[:, None]])
        frame = cv2.warpAffine(big, full, (w, h), flags=cv2.INTER_LINEAR)
        A = est(frame)
        if k == 0:
            assert A is None
        else:
            # the motion since the previous frame: A_k composed with the inverse of A_{k-1}
            prev = np.vstack([A_prev, [0, 0, 1]])
            step = (np.vstack([A_true, [0, 0, 1]]) @ np.linalg.inv(prev))[:2]
            corners = np.array([[0, 0], [w, 0], [0, h], [w, h]], dtype=float)
            errs.append(np.abs(corners @ A[:, :2].T + A[:, 2]
                               - (corners @ step[:, :2].T + step[:, 2])).max())
        A_prev = A_true
    assert found[0] == (270, 480) and len(found) < 5  # halved twice; corners followed
    assert max(errs) < 0.5, errs


def test_a_colour_frame_is_shrunk_before_its_grey_is_taken():
    """The analysed grey image of a colour frame: its first halvings are one bilinear
    shrink, each pixel the mean of the 2x2 at the centre of its block (at one halving
    the whole block), then the grey conversion, then halvings of the grey by averaging;
    within a grey level of taking the grey first and averaging whole blocks."""
    from pgm.observation.camera_motion import COLOUR_HALVINGS, _grey

    def mean2x2(a, first=0, step=2):  # the mean of the 2x2 at (first, first) of each block
        a = a.astype(float)
        return sum(a[first + i::step, first + j::step] for i in (0, 1) for j in (0, 1)) / 4

    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (64, 96, 3), dtype=np.uint8)
    grey = lambda a: cv2.cvtColor(a, cv2.COLOR_BGR2GRAY)  # noqa: E731
    as_u8 = lambda a: np.rint(a).astype(np.uint8)  # noqa: E731
    assert np.abs(_grey(img, halvings=1).astype(int)
                  - grey(as_u8(mean2x2(img))).astype(int)).max() <= 1
    assert COLOUR_HALVINGS == 2
    assert np.abs(_grey(img, halvings=2).astype(int)
                  - grey(as_u8(mean2x2(img, 1, 4))).astype(int)).max() <= 1
    g3 = _grey(img, halvings=3)  # the third halving averages the grey
    assert g3.shape == (8, 12)
    np.testing.assert_allclose(g3, mean2x2(_grey(img, halvings=2)), atol=0.5)
    # a grey frame is averaged whole, as before
    gimg = grey(img)
    np.testing.assert_allclose(_grey(gimg, halvings=1), mean2x2(gimg), atol=0.5)


def test_the_pyramid_follows_a_pan_stated_in_frame_widths_per_second():
    """The default pyramid's reach, ``win_size // 2 · 2**levels`` analysed pixels, covers
    ``MAX_PAN`` frame widths a second at the video's frame rate: deeper at 10 frames/s
    than at 30; a given depth is kept; the estimator counts its own time."""
    from pgm.observation.camera_motion import MAX_PAN

    def levels(w, h, fps, **kw):
        est = CameraMotionEstimator("on", fps=fps, **kw)
        est(np.zeros((h, w, 3), np.uint8))
        reach = (est.win_size // 2) * 2 ** est.pyramid_levels / est._scale  # full-res px
        return est, reach

    for w, h, fps in ((1920, 1080, 30.0), (1280, 720, 10.0), (640, 480, 25.0)):
        est, reach = levels(w, h, fps)
        assert reach >= MAX_PAN * w / fps and est.seconds > 0
    assert levels(1280, 720, 10.0)[0].pyramid_levels > levels(1280, 720, 30.0)[0].pyramid_levels
    assert levels(1920, 1080, 30.0, pyramid_levels=2)[0].pyramid_levels == 2
    with pytest.raises(ValueError, match="fps"):
        CameraMotionEstimator("on", fps=0.0)
