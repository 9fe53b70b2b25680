"""Image sequences decode ahead on a thread (issue 26, item 11): the frames, the errors
and where they are raised are those of decoding one frame at a time, and a caller that
stops early leaves at most PREFETCH frames decoded for nothing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import pgm.io.video as video
from pgm.core.errors import InputError
from pgm.io.prefetch import read_ahead
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


def test_read_ahead_gives_the_items_and_the_error_where_it_happened():
    """Video files decode on a thread of their own (issue 39, item 2): the producer's
    items in order, its exception raised at the item where it happened."""
    def items():
        yield from range(5)
        raise InputError("frame 6 is corrupt")

    got = []
    with pytest.raises(InputError, match="frame 6"):
        for x in read_ahead(items(), 2):
            got.append(x)
    assert got == list(range(5))


def test_read_ahead_stopped_early_stops_and_closes_the_producer():
    import threading

    closed = threading.Event()
    made = []

    def items():
        try:
            for k in range(1000):
                made.append(k)
                yield k
        finally:
            closed.set()

    it = read_ahead(items(), 2)
    assert [next(it), next(it)] == [0, 1]
    it.close()
    assert closed.wait(5) and len(made) <= 2 + 2 + 2  # two used, at most a few ahead
    assert not any(t.name == "pgm-decode-video" and t.is_alive()
                   for t in threading.enumerate())


def test_a_video_file_reads_ahead_the_same_frames(tmp_path):
    scene = demo_scene(seed=0, n_frames=6)
    path = tmp_path / "clip.avi"
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0,
                          scene.frames[0].shape[1::-1])
    for f in scene.frames:
        out.write(f)
    out.release()
    src = open_source(path)
    cap = cv2.VideoCapture(str(path))
    want = [cap.read()[1] for _ in range(6)]
    cap.release()
    got = list(src)
    assert [k for k, _ in got] == list(range(1, 7))
    for (_, img), w in zip(got, want, strict=True):
        np.testing.assert_array_equal(img, w)
    assert [k for k, _ in src.frames(2, 4)] == [2, 3]
