"""The correlation filter's colour channels (``colour=True``): the window's CIE Lab chroma
beside grey and gradients — two objects of the same grey level told apart, a grey video
unchanged, the option saved."""

import numpy as np
import pytest

from pgm.core.factor import factor_from_dict
from pgm.core.frame import FrameContext
from pgm.observation.appearance.cf_features import CHROMA_UNIT, chroma_frame
from pgm.observation.appearance.correlation import CorrelationFilterLikelihood


def _two_squares() -> np.ndarray:
    """A red and a green square of the same grey level (60) on a grey background."""
    img = np.full((120, 240, 3), 128, np.uint8)
    img[45:75, 45:75] = (0, 0, 200)  # BGR red: grey 0.299 x 200 = 59.8
    img[45:75, 165:195] = (0, 102, 0)  # green: grey 0.587 x 102 = 59.9
    return img


def test_colour_tells_apart_what_grey_cannot():
    import cv2

    img = _two_squares()
    g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)  # the squares' grey levels are equal
    assert g[60, 60] == g[60, 180]
    red, green = np.array([[60.0, 60, 30, 30]]), np.array([[180.0, 60, 30, 30]])
    gap = {}
    for colour in (False, True):
        cf = CorrelationFilterLikelihood("object", colour=colour)
        cf.initialize(FrameContext(1, img), red[0])
        ll_red = cf.log_likelihood(red, FrameContext(2, img))[0]
        ll_green = cf.log_likelihood(green, FrameContext(2, img))[0]
        gap[colour] = ll_red - ll_green
    assert gap[False] == pytest.approx(0.0, abs=1e-6)  # grey alone: the same object
    assert gap[True] > 0.2 * CorrelationFilterLikelihood("object").lam  # colour: not


def test_chroma_is_zero_on_grey_and_saved_with_the_factor():
    grey_bgr = np.repeat(np.arange(0, 240, 2, dtype=np.uint8)[None, :, None], 3, axis=2)
    assert np.abs(chroma_frame(grey_bgr)).max() * CHROMA_UNIT < 0.5  # under a Lab unit
    assert chroma_frame(grey_bgr[:, :, 0]).shape == grey_bgr.shape[:2] + (2,)
    red = chroma_frame(np.full((2, 2, 3), (0, 0, 255), np.uint8))[0, 0] * CHROMA_UNIT
    assert red[0] > 60 and red[1] > 40  # CIE Lab red: a* about 80, b* about 67
    cf = CorrelationFilterLikelihood("object", colour=True)
    assert factor_from_dict(cf.to_dict()).colour is True
    assert "colour" not in CorrelationFilterLikelihood("object").params()
    with pytest.raises(ValueError, match="colour"):
        CorrelationFilterLikelihood("object", colour="yes")
