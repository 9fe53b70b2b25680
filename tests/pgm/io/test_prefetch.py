"""Image sequences decode ahead on a thread (issue 26, item 11): the frames, the errors
and where they are raised are those of decoding one frame at a time, and a caller that
stops early leaves at most PREFETCH frames decoded for nothing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import pgm.io.video as video
from pgm.core.errors import InputError
from pgm.io.video import PREFETCH, open_source
from pgm.synthetic import demo_scene


@pytest.fixture
def seq(tmp_path):
    demo_scene(seed=0, n_frames=8).write_otb(tmp_path / "seq")
    return tmp_path / "seq"


@pytest.fixture
def reads(monkeypatch):
    """The files decoded, in order."""
    seen = []
    real = video._read_image

    def spy(path):
        seen.append(path.name)
        return real(path)

    monkeypatch.setattr(video, "_read_image", spy)
    return seen


def test_same_frames_in_order(seq):
    src = open_source(seq)
    got = list(src)
    assert [k for k, _ in got] == list(range(1, 9))
    for (_, img), f in zip(got, src.files, strict=True):
        np.testing.assert_array_equal(img, cv2.imread(str(f)))
    assert [k for k, _ in src.frames(3, 6)] == [3, 4, 5]


def test_a_corrupt_frame_fails_when_reached_not_before(seq):
    files = sorted((seq / "img").iterdir())
    files[2].write_bytes(b"not a png")
    it = iter(open_source(seq))
    assert [next(it)[0], next(it)[0]] == [1, 2]  # frame 3 is decoded ahead, and failed
    with pytest.raises(InputError, match=files[2].name):
        next(it)


def test_stopping_early_decodes_little_more(seq, reads):
    it = iter(open_source(seq))
    next(it)
    it.close()
    assert len(reads) <= 1 + PREFETCH
    assert reads == sorted(reads)
    before = len(reads)
    src = open_source(seq)
    assert [k for k, _ in src.frames(6)] == [6, 7, 8]
    assert reads[before:] == [f.name for f in src.files[5:]]  # skipped files never read
