"""The scale filter (DSST's one-dimensional filter over scale): it reads the size the
object was scaled by, its settings are checked and saved, and over a long video of a
constant-size object the size it holds does not drift."""

import cv2
import numpy as np
import pytest
from test_correlation import (  # same folder: on sys.path
    check_unlearned_refuses_and_saved_settings_load,
    scene,
)

from pgm.core.frame import FrameContext
from pgm.observation.appearance.scale_filter import ScaleFilterLikelihood


@pytest.mark.parametrize("factor", [0.91, 1.0, 1.06, 1.12])
def test_reads_the_size_the_object_was_scaled_by(factor):
    rng = np.random.default_rng(2)
    f = ScaleFilterLikelihood("object")
    f.initialize(FrameContext(1, scene(rng, (130, 100))), np.array([130.0, 100, 40, 56]))
    img = scene(rng, (130, 100), scale=factor)
    sizes = np.exp(np.linspace(np.log(0.8), np.log(1.25), 61))
    x = np.array([[130.0, 100, 40 * s, 56 * s] for s in sizes])
    ll = f.log_likelihood(x, FrameContext(2, img))
    # within one sample (3 %) of the true factor; the scene redraws the object rounded to
    # whole pixels, so the drawn factor itself is known to about a pixel in 40
    assert abs(np.log(sizes[np.argmax(ll)] / factor)) <= np.log(f.scale_step)
    assert ll.max() > 0.5 * f.lam  # a typical peak scores about lam


def test_reading_is_the_same_whichever_size_the_particles_are_centred_on():
    """The frame's stack is taken at the particles' mean size: whether they sit a sample
    below or above the truth, the best particle is the true size."""
    rng = np.random.default_rng(3)
    f = ScaleFilterLikelihood("object")
    f.initialize(FrameContext(1, scene(rng, (130, 100))), np.array([130.0, 100, 40, 56]))
    img = scene(rng, (130, 100), scale=1.06)
    for centre in (0.98, 1.14):
        sizes = centre * np.exp(np.linspace(-0.12, 0.12, 25))
        x = np.array([[130.0, 100, 40 * s, 56 * s] for s in sizes])
        ll = f.log_likelihood(x, FrameContext(2, img))
        assert abs(np.log(sizes[np.argmax(ll)] / 1.06)) <= np.log(f.scale_step)


def test_settings_are_checked_and_saved_with_the_model(tmp_path):
    for bad in ({"lam": float("nan")}, {"n_scales": 16}, {"n_scales": 1},
                {"scale_step": 1.0}, {"patch_px": 0}, {"sigma": -1}):
        with pytest.raises(ValueError):
            ScaleFilterLikelihood("object", **bad)
    check_unlearned_refuses_and_saved_settings_load(
        ScaleFilterLikelihood("object", lam=7.0, n_scales=9), tmp_path)


def test_the_size_does_not_drift_over_a_long_video():
    """A constant-size object moving for 600 frames. The position filter's own scale
    levels read the size a few per cent small and learn at that size, so its size drifts
    down; read by the scale filter alone (``cf(scales=1)+scale``), which is trained to
    peak at its estimate's size, it stays near the truth."""
    from pgm.inference import Engine
    from pgm.models import single_object
    from pgm.synthetic.scene import _sensor_noise, _smooth_noise

    rng = np.random.default_rng(0)
    H, W, ow, oh = 240, 320, 40, 48
    bg = 120.0 + 22.0 * _smooth_noise(rng, H, W, 14, 18, 1)[..., 0]
    tex = _smooth_noise(rng, oh, ow, 5, 4, 1) + 0.5 * _smooth_noise(rng, oh, ow, 12, 10, 1)
    obj = np.clip(128.0 + 40.0 * tex[..., 0] / tex.std(), 0, 255)
    sizes = {}
    for app in ("cf", "cf(scales=1)+scale"):
        eng = Engine(single_object.build_graph(single_object.Params(
            init_box=(160, 120, ow, oh), appearance=app)), np.random.default_rng(0))
        out = []
        noise = np.random.default_rng(1)
        for t in range(600):
            cx = 160 + 60 * np.sin(2 * np.pi * t / 150)
            cy = 120 + 30 * np.sin(2 * np.pi * t / 97)
            img = bg.copy()
            x0, y0 = int(round(cx - ow / 2)), int(round(cy - oh / 2))
            img[y0:y0 + oh, x0:x0 + ow] = obj
            img = np.clip(img + _sensor_noise(noise, img.shape, 4.0), 0, 255).astype(np.uint8)
            est = eng.step(FrameContext(t + 1, cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)))
            e = est.estimates["object"]
            out.append(np.sqrt(e[2] * e[3] / (ow * oh)))
        sizes[app] = np.mean(out[-100:])
    assert abs(np.log(sizes["cf(scales=1)+scale"])) < 0.06
    assert sizes["cf"] < sizes["cf(scales=1)+scale"]
