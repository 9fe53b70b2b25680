"""Issue 26, item 8: the annotated video's caption is drawn once, on a plate measured
with the text's own font scale and thickness, and text and markers grow with the frame,
so a 1920x1080 caption is as readable as a 640x480 one."""

from __future__ import annotations

import numpy as np
import pytest

from pgm.plotting.annotate import annotate, drawing_scale

CAPTION = "part-graph frame 123 ESS 10/10/10"


def _caption(height: int, width: int):
    """The caption drawn on a mid-grey frame: the bounding boxes ``(x0, y0, x1, y1)`` of
    its white text pixels and of its black plate."""
    img = annotate(np.full((height, width, 3), 128, np.uint8), text=CAPTION)
    grey = img.astype(int).sum(axis=2) // 3

    def bbox(mask):
        ys, xs = np.nonzero(mask)
        return xs.min(), ys.min(), xs.max() + 1, ys.max() + 1

    return bbox(grey > 200), bbox(grey < 10)


@pytest.mark.parametrize("height, width", [(480, 640), (1080, 1920), (720, 1280)])
def test_caption_height_grows_with_the_frame(height, width):
    (tx0, ty0, tx1, ty1), _ = _caption(height, width)
    (_, r0, _, r1), _ = _caption(480, 640)
    ratio = (ty1 - ty0) / (r1 - r0)
    assert ratio == pytest.approx(height / 480, rel=0.2)
    assert (ty1 - ty0) >= 0.02 * height  # capitals at least 2 % of the frame high
    assert tx1 < width  # the whole caption fits


def test_caption_text_lies_on_its_plate():
    """One measurement for the plate and the text: every text pixel is on the plate, and
    the plate is no more than a small margin larger than the text."""
    for h, w in [(480, 640), (1080, 1920)]:
        (tx0, ty0, tx1, ty1), (px0, py0, px1, py1) = _caption(h, w)
        assert px0 <= tx0 and py0 <= ty0 and tx1 <= px1 and ty1 <= py1
        margin = 8 * drawing_scale(np.zeros((h, w)))
        assert tx0 - px0 <= margin and px1 - tx1 <= margin


def test_markers_grow_with_the_frame():
    def dot_area(h, w):
        img = annotate(np.zeros((h, w, 3), np.uint8),
                       particles={"object": np.array([[w / 2, h / 2]])},
                       particle_weights={"object": np.array([1.0])})
        return int(np.count_nonzero(img.any(axis=2)))

    assert dot_area(1080, 1920) > 3 * dot_area(480, 640)


def test_small_frames_are_drawn_at_the_base_size():
    assert drawing_scale(np.zeros((240, 320, 3))) == 1.0
    assert drawing_scale(np.zeros((1080, 1920, 3))) == pytest.approx(2.25)
