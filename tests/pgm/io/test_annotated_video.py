"""The annotated video: H.264 that browsers play (PyAV), OpenCV's ``mp4v`` as fallback."""

from __future__ import annotations

import json
import sys

import cv2
import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.io.annotated_video import AnnotatedVideoWriter, h264_available


def _frames(n: int, w: int = 83, h: int = 61) -> list[np.ndarray]:
    """Odd-sized frames with a moving white square (distinct frames)."""
    out = []
    for i in range(n):
        img = np.full((h, w, 3), 30 + 5 * i, np.uint8)
        img[10:25, 2 * i:2 * i + 15] = 255
        out.append(img)
    return out


def _probe(path) -> tuple[str, str, int, int, int]:
    """Codec, pixel format, width, height and decoded frame count (read back by PyAV)."""
    import av

    with av.open(str(path)) as c:
        s = c.streams.video[0]
        name, fmt, w, h = s.codec_context.name, s.codec_context.pix_fmt, s.width, s.height
        n = sum(1 for _ in c.decode(video=0))
    return name, fmt, w, h, n


needs_h264 = pytest.mark.skipif(not h264_available(),
                                reason="PyAV with libx264 is not installed (pip install av)")


@needs_h264
def test_h264_by_default_browser_ready(tmp_path):
    path = tmp_path / "a.mp4"
    frames = _frames(12)
    with AnnotatedVideoWriter(path, fps=12.5) as video:
        for f in frames:
            video.write(f)
        video.write(frames[0][:, :, 0])  # a grey frame is converted
    assert video.codec == "h264" and video.frames_written == 13
    assert video.size == (84, 62)  # padded to even width and height (yuv420p)
    name, fmt, w, h, n = _probe(path)
    assert (name, fmt, w, h, n) == ("h264", "yuv420p", 84, 62, 13)
    cap = cv2.VideoCapture(str(path))  # OpenCV reads it too, frame by frame
    decoded = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        decoded.append(img)
    cap.release()
    assert len(decoded) == 13
    # the content survives the encoding (the moving square, lossy but close)
    err = np.abs(decoded[5][:61, :83].astype(float) - frames[5].astype(float)).mean()
    assert err < 6.0


def test_opencv_fallback_when_pyav_is_missing(tmp_path, monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "av", None)  # "import av" raises ImportError
    path = tmp_path / "b.mp4"
    with caplog.at_level("WARNING", logger="pgm"):
        with AnnotatedVideoWriter(path, fps=10) as video:
            for f in _frames(5):
                video.write(f)
    assert video.codec == "mp4v" and video.size == (83, 61)
    assert "mp4v" in caplog.text
    with pytest.raises(InputError, match="H.264"):
        AnnotatedVideoWriter(tmp_path / "c.mp4", codec="h264").write(_frames(1)[0])
    monkeypatch.undo()
    cap = cv2.VideoCapture(str(path))
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode().lower()
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    assert fourcc in ("mp4v", "fmp4") and n == 5  # FFmpeg calls MPEG-4 part 2 'FMP4'
    if h264_available():
        assert _probe(path)[0] == "mpeg4"


def test_codec_is_checked_and_mp4v_can_be_asked_for(tmp_path):
    with pytest.raises(ValueError, match="unknown video codec"):
        AnnotatedVideoWriter(tmp_path / "x.mp4", codec="vp9")
    with AnnotatedVideoWriter(tmp_path / "m.mp4", codec="mp4v") as video:
        video.write(_frames(1)[0])
    assert video.codec == "mp4v"


@needs_h264
def test_symlink_is_replaced_not_followed(tmp_path):
    victim = tmp_path / "precious.txt"
    victim.write_text("keep")
    link = tmp_path / "v.mp4"
    link.symlink_to(victim)
    with AnnotatedVideoWriter(link) as video:
        video.write(_frames(1)[0])
    assert victim.read_text() == "keep" and not link.is_symlink()


@needs_h264
def test_interrupted_writer_is_finalised(tmp_path):
    """Closing after an exception (what the runners do on SIGINT/SIGTERM) flushes the
    encoder's delayed frames: every frame written is in a playable file."""
    path = tmp_path / "cut.mp4"
    video = AnnotatedVideoWriter(path, fps=25)
    with pytest.raises(KeyboardInterrupt):
        try:
            for i, f in enumerate(_frames(20)):
                if i == 9:
                    raise KeyboardInterrupt
                video.write(f)
        finally:
            video.close()
    assert _probe(path)[4] == 9


@needs_h264
def test_track_writes_h264_and_says_so(tmp_path):
    from pgm.app.runner import track
    from pgm.models import colour_pf
    from pgm.synthetic import demo_scene

    seq = demo_scene(seed=0, n_frames=4).write_otb(tmp_path / "seq")
    g = colour_pf.build_graph(colour_pf.Params(init_box=(35, 140, 30, 80)))
    track(seq, g, rng=np.random.default_rng(0), out_dir=tmp_path / "out", progress=False,
          num_particles=20)
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    assert run["video_codec"] == "h264"
    name, _, w, h, n = _probe(tmp_path / "out" / "annotated.mp4")
    assert (name, w, h, n) == ("h264", 320, 240, 4)


@needs_h264
def test_a_large_frame_is_written_at_1280_on_its_long_side_by_default(tmp_path):
    from pgm.io.annotated_video import DEFAULT_MAX_SIDE, video_scale

    frame = np.full((1080, 1920, 3), 90, np.uint8)
    cv2.rectangle(frame, (600, 300), (900, 700), (0, 0, 255), -1)
    with AnnotatedVideoWriter(tmp_path / "big.mp4", fps=25) as video:
        for _ in range(3):
            video.write(frame)
    assert video.size == (1280, 720) and video.frames_written == 3
    assert _probe(tmp_path / "big.mp4")[4] == 3
    with AnnotatedVideoWriter(tmp_path / "half.mp4", fps=25, scale=0.5) as video:
        video.write(frame)
    assert video.size == (960, 540)
    assert video_scale((640, 480)) == 1.0 and video_scale((2560, 1440)) == DEFAULT_MAX_SIDE / 2560
    with pytest.raises(InputError, match=r"scale must be in \(0, 1\]"):
        AnnotatedVideoWriter(tmp_path / "x.mp4", scale=1.5)


@needs_h264
def test_the_background_encoder_writes_what_the_foreground_one_does(tmp_path):
    frames = _frames(12)
    for background in (True, False):
        with AnnotatedVideoWriter(tmp_path / f"{background}.mp4", fps=10,
                                  background=background) as video:
            for f in frames:
                video.write(f)
        assert video.frames_written == 12
    a, b = (_probe(tmp_path / f"{bg}.mp4") for bg in (True, False))
    assert a == b


def test_an_encoder_failure_reaches_the_caller(tmp_path):
    class Broken:
        codec = "mp4v"

        def __init__(self, *a):
            pass

        def write(self, image):
            raise OSError("disk full")

        def close(self):
            pass

    video = AnnotatedVideoWriter(tmp_path / "f.mp4", codec="mp4v")
    import pgm.io.annotated_video as av_mod
    original = av_mod._OpenCVSink
    av_mod._OpenCVSink = Broken
    try:
        with pytest.raises(InputError, match="cannot write video .*OSError: disk full"):
            for f in _frames(30):
                video.write(f)
            video.close()
    finally:
        av_mod._OpenCVSink = original
