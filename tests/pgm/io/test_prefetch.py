"""Image sequences decode ahead in a thread (issue 26, item 11): the frames, the errors
and where they are raised are those of decoding one frame at a time."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.io.video import open_source
from pgm.synthetic import demo_scene


@pytest.fixture
def seq(tmp_path):
    demo_scene(seed=0, n_frames=6).write_otb(tmp_path / "seq")
    return tmp_path / "seq"


def _decoders():
    return [t for t in threading.enumerate() if t.name == "pgm-decode"]


def test_same_frames_in_order(seq):
    src = open_source(seq)
    got = list(src)
    assert [k for k, _ in got] == [1, 2, 3, 4, 5, 6]
    import cv2

    for (_, img), f in zip(got, src.files, strict=True):
        np.testing.assert_array_equal(img, cv2.imread(str(f)))
    assert list(src.frames(3, 5))[0][0] == 3 and len(list(src.frames(3, 5))) == 2
    assert not _decoders()


def test_a_corrupt_frame_fails_when_reached_not_before(seq):
    files = sorted((seq / "img").iterdir())
    files[2].write_bytes(b"not a png")
    it = iter(open_source(seq))
    assert [next(it)[0], next(it)[0]] == [1, 2]  # frame 3 is decoded ahead, and failed
    with pytest.raises(InputError, match=files[2].name):
        next(it)
    assert not _decoders()


def test_stopping_early_stops_the_thread(seq):
    it = iter(open_source(seq))
    next(it)
    it.close()
    assert not _decoders()
