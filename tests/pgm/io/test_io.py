"""Tests for pgm.io.video and pgm.io.annotations."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.io.annotations import (
    MotTable,
    MotWriter,
    SingleTrack,
    detect_gt_format,
    load_mot,
    load_single_gt,
    load_tracks,
)
from pgm.io.video import ImageSequenceSource, VideoSource, natural_key, open_source


def _png(path: Path, value: int, shape: tuple[int, ...] = (12, 16, 3)) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.full(shape, value, dtype=np.uint8))


def _raises_one_line(exc_info: pytest.ExceptionInfo, *needles: str) -> None:
    message = str(exc_info.value)
    assert "\n" not in message
    for needle in needles:
        assert needle in message, (needle, message)


# --------------------------------------------------------------------------- frame sources


def test_missing_path(tmp_path: Path) -> None:
    missing = tmp_path / "nope"
    with pytest.raises(InputError) as e:
        open_source(missing)
    _raises_one_line(e, str(missing))


def test_empty_folder(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("not an image")
    with pytest.raises(InputError) as e:
        open_source(tmp_path)
    _raises_one_line(e, str(tmp_path), "no image")


def test_corrupt_video(tmp_path: Path) -> None:
    bad = tmp_path / "x.mp4"
    bad.write_bytes(np.random.default_rng(0).integers(0, 256, 300, dtype=np.uint8).tobytes())
    with pytest.raises(InputError) as e:
        open_source(bad)
    _raises_one_line(e, str(bad))


def test_single_image_is_not_a_source(tmp_path: Path) -> None:
    _png(tmp_path / "a.png", 1)
    with pytest.raises(InputError) as e:
        open_source(tmp_path / "a.png")
    _raises_one_line(e, "a.png")


def test_plain_folder_natural_order_grey_and_range(tmp_path: Path) -> None:
    for k in (1, 2, 10):
        _png(tmp_path / f"img{k}.png", k)
    _png(tmp_path / "img3.png", 3, shape=(12, 16))  # greyscale
    src = open_source(tmp_path)
    assert isinstance(src, ImageSequenceSource)
    assert src.layout == "images" and src.gt_path is None and src.gt_format is None
    assert src.det_path is None and src.fps == 25.0 and src.name == tmp_path.name
    assert len(src) == 4 and src.size == (16, 12)
    got = [(n, int(im[0, 0, 0]), im.shape, im.dtype) for n, im in src]
    assert got == [(1, 1, (12, 16, 3), np.uint8), (2, 2, (12, 16, 3), np.uint8),
                   (3, 3, (12, 16, 3), np.uint8), (4, 10, (12, 16, 3), np.uint8)]
    assert [n for n, _ in src.frames(2, 4)] == [2, 3]
    assert [n for n, _ in src.frames(4)] == [4]
    with pytest.raises(InputError):
        list(src.frames(0))


def test_corrupt_png_named_and_skipped_files_not_read(tmp_path: Path) -> None:
    _png(tmp_path / "0001.png", 10)
    (tmp_path / "0002.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 10)
    _png(tmp_path / "0003.png", 30)
    src = open_source(tmp_path)
    assert len(src) == 3
    # a sub-range that skips the corrupt file never reads it
    assert [n for n, _ in src.frames(3)] == [3]
    frames = src.frames()
    assert next(frames)[0] == 1
    with pytest.raises(InputError) as e:
        next(frames)
    _raises_one_line(e, "0002.png")


def test_video_roundtrip(tmp_path: Path) -> None:
    path = tmp_path / "clip.mp4"
    _write_video(path)
    src = open_source(path)
    assert isinstance(src, VideoSource)
    assert src.layout == "video" and src.name == "clip" and src.gt_path is None
    assert len(src) == 10 and src.size == (64, 48) and src.fps == pytest.approx(12.0)
    frames = list(src)
    assert [n for n, _ in frames] == list(range(1, 11))
    assert all(im.shape == (48, 64, 3) and im.dtype == np.uint8 for _, im in frames)
    # lossy codec: grey levels roughly preserved and increasing
    means = [float(im.mean()) for _, im in frames]
    assert np.all(np.diff(means) > 5)
    sub = list(src.frames(4, 7))
    assert [n for n, _ in sub] == [4, 5, 6]
    np.testing.assert_array_equal(sub[0][1], frames[3][1])


def _write_video(path: Path, n: int = 10) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 12.0, (64, 48))
    assert writer.isOpened()
    for k in range(n):
        writer.write(np.full((48, 64, 3), 20 * k, dtype=np.uint8))
    writer.release()


def test_mot_folder_holding_a_video(tmp_path: Path) -> None:
    # the PETS09-S2L1-video layout: seqinfo.ini + gt/ + one video, no img1/
    root = tmp_path / "seq"
    (root / "gt").mkdir(parents=True)
    (root / "seqinfo.ini").write_text("[Sequence]\nname=Seq\nimDir=img1\nframeRate=7\n")
    (root / "gt" / "gt.txt").write_text("1,1,1,1,5,5,1,-1,-1,-1\n")
    _write_video(root / "clip.mp4", 4)
    src = open_source(root)
    assert isinstance(src, VideoSource) and src.layout == "mot" and src.name == "Seq"
    assert src.fps == 7.0 and len(src) == 4 and src.gt_path == root / "gt" / "gt.txt"
    assert src.det_path is None
    # the video file itself keeps the container's rate and finds the folder's gt
    direct = open_source(root / "clip.mp4")
    assert direct.fps == pytest.approx(12.0) and direct.gt_path == root / "gt" / "gt.txt"


def test_otb_folder_with_empty_img(tmp_path: Path) -> None:
    (tmp_path / "img").mkdir()
    (tmp_path / "groundtruth_rect.txt").write_text("1,1,2,2\n")
    with pytest.raises(InputError) as e:
        open_source(tmp_path)
    _raises_one_line(e, str(tmp_path / "img"))


def _mot_folder(root: Path, *, seqinfo: str | None = None, n: int = 3) -> Path:
    root.mkdir()
    (root / "seqinfo.ini").write_text(seqinfo if seqinfo is not None else
                                      "[Sequence]\nname=Toy\nimDir=img1\nframeRate=7\n"
                                      f"seqLength={n}\nimWidth=16\nimHeight=12\nimExt=.png\n")
    for k in range(1, n + 1):
        _png(root / "img1" / f"{k:06d}.png", k)
    (root / "gt").mkdir()
    (root / "gt" / "gt.txt").write_text(
        "1,1,11,21,10,20,1,-1,-1,-1\n1,2,31,41,5,6,0,-1,-1,-1\n"
        "2,1,12,22,10,20,1,-1,-1,-1\n3,1,13,23,10,20,1,-1,-1,-1\n")
    (root / "det").mkdir()
    (root / "det" / "det.txt").write_text(
        "1,-1,11,21,10,20,0.9,-1,-1,-1\n1,-1,50,50,10,10,0.2,-1,-1,-1\n"
        "2,-1,12,22,10,20,0.8,-1,-1,-1\n")
    return root


def test_mot_folder(tmp_path: Path) -> None:
    root = _mot_folder(tmp_path / "Toy-01")
    src = open_source(root)
    assert src.layout == "mot" and src.name == "Toy" and src.fps == 7.0
    assert len(src) == 3 and src.size == (16, 12)
    assert src.gt_path == root / "gt" / "gt.txt" and src.gt_format == "mot"
    assert src.det_path == root / "det" / "det.txt"
    assert [(n, int(im[0, 0, 1])) for n, im in src] == [(1, 1), (2, 2), (3, 3)]


@pytest.mark.parametrize("text, needle", [
    ("name=Toy\nframeRate=7\n", "seqinfo.ini"),                     # no section header
    ("[Other]\nname=Toy\n", "[Sequence]"),                          # wrong section
    ("[Sequence]\nframeRate=fast\nimExt=.png\n", "frameRate"),      # not a number
    ("[Sequence]\nseqLength=2.5\nimExt=.png\n", "seqLength"),       # not an integer
])
def test_malformed_seqinfo(tmp_path: Path, text: str, needle: str) -> None:
    root = _mot_folder(tmp_path / "seq", seqinfo=text)
    with pytest.raises(InputError) as e:
        open_source(root)
    _raises_one_line(e, str(root / "seqinfo.ini"), needle)


def test_otb_folder_and_gt(tmp_path: Path) -> None:
    root = tmp_path / "Walker"
    for k in range(1, 5):
        _png(root / "img" / f"{k:04d}.png", k)
    (root / "groundtruth_rect.txt").write_text("11\t21\t10\t20\nNaN,NaN,NaN,NaN\n"
                                               "13 23  10 20\n0,0,0,0\n")
    src = open_source(root)
    assert src.layout == "otb" and len(src) == 4 and src.gt_format == "otb"
    gt = load_single_gt(src.gt_path, src.gt_format)
    assert isinstance(gt, SingleTrack)
    np.testing.assert_array_equal(gt.frames, [1, 3])
    np.testing.assert_allclose(gt.boxes, [[10, 20, 10, 20], [12, 22, 10, 20]])
    assert gt.frames.dtype.kind == "i" and gt.boxes.dtype == float


def test_miltrack_folder_and_gt(tmp_path: Path) -> None:
    root = tmp_path / "Face"
    for k in range(4):
        _png(root / "imgs" / f"img{k:05d}.png", k + 1, shape=(12, 16))
    (root / "face_gt.txt").write_text("120.5,71.474,116,146\n0,0,0,0\n0,0,0,0\n3,4,5,6")
    (root / "face_frames.txt").write_text("2,5")
    src = open_source(root)
    assert src.layout == "miltrack" and len(src) == 4
    assert src.gt_path == root / "face_gt.txt" and src.gt_format == "miltrack"
    assert [(n, int(im[0, 0, 2])) for n, im in src] == [(1, 1), (2, 2), (3, 3), (4, 4)]
    gt = load_single_gt(src.gt_path)  # auto: *_gt.txt -> miltrack, 0-based, no shift
    np.testing.assert_array_equal(gt.frames, [1, 4])
    np.testing.assert_allclose(gt.boxes, [[120.5, 71.474, 116, 146], [3, 4, 5, 6]])


def test_detect_gt_format(tmp_path: Path) -> None:
    (tmp_path / "boxes.txt").write_text("1,1,10,10,5,5,1\n")
    (tmp_path / "other.txt").write_text("1 2 3 4\n")
    assert detect_gt_format(tmp_path / "groundtruth_rect.txt") == "otb"
    assert detect_gt_format(tmp_path / "gt.txt") == "mot"
    assert detect_gt_format(tmp_path / "faceocc_gt.txt") == "miltrack"
    assert detect_gt_format(tmp_path / "boxes.txt") == "mot"
    assert detect_gt_format(tmp_path / "other.txt") == "otb"


@pytest.mark.parametrize("fmt, text, line", [
    ("otb", "1,2,3,4\n1,2,3\n", 2),             # wrong column count
    ("otb", "1,2,3,4\n1,2,3,4\nx,y,w,h\n", 3),  # text
    ("miltrack", "1,2,3,4\n\n1,2,3,4\n", 2),    # blank line inside the file
    ("otb", "1,2,3,4,5\n", 1),
])
def test_malformed_single_gt(tmp_path: Path, fmt: str, text: str, line: int) -> None:
    path = tmp_path / "groundtruth_rect.txt"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        load_single_gt(path, fmt)
    _raises_one_line(e, f"{path}:{line}")


def test_single_gt_errors(tmp_path: Path) -> None:
    path = tmp_path / "groundtruth_rect.txt"
    path.write_text("0,0,0,0\nnan,nan,nan,nan\n")
    with pytest.raises(InputError) as e:
        load_single_gt(path)
    _raises_one_line(e, str(path))
    with pytest.raises(InputError) as e:
        load_single_gt(path, "vot")
    _raises_one_line(e, "vot", str(path))
    with pytest.raises(InputError) as e:
        load_single_gt(tmp_path / "missing_gt.txt")
    _raises_one_line(e, "missing_gt.txt")


def test_single_gt_from_mot(tmp_path: Path) -> None:
    path = tmp_path / "gt.txt"
    path.write_text("2,7,11,21,10,20,1,-1,-1,-1\n1,5,1,1,4,4,1,-1,-1,-1\n"
                    "1,7,10,20,10,20,1,-1,-1,-1\n3,5,2,2,4,4,0,-1,-1,-1\n")
    first = load_single_gt(path)  # first identity in frame order: 5
    np.testing.assert_array_equal(first.frames, [1])  # frame 3 is flag 0: not scored
    np.testing.assert_allclose(first.boxes, [[0, 0, 4, 4]])
    seven = load_single_gt(path, "mot", obj_id=7)
    np.testing.assert_array_equal(seven.frames, [1, 2])
    np.testing.assert_allclose(seven.boxes, [[9, 19, 10, 20], [10, 20, 10, 20]])
    with pytest.raises(InputError) as e:
        load_single_gt(path, obj_id=99)
    _raises_one_line(e, "99", str(path))


def test_load_mot_gt_ignore_and_index(tmp_path: Path) -> None:
    root = _mot_folder(tmp_path / "seq")
    gt = load_mot(root / "gt" / "gt.txt")
    assert isinstance(gt, MotTable) and len(gt) == 4
    np.testing.assert_array_equal(gt.ignore, [False, True, False, False])
    np.testing.assert_array_equal(gt.frame_numbers(), [1, 2, 3])
    ids, boxes, conf = gt.at(1)
    np.testing.assert_array_equal(ids, [1, 2])
    np.testing.assert_allclose(boxes, [[10, 20, 10, 20], [30, 40, 5, 6]])
    np.testing.assert_allclose(conf, [1, 0])
    ids, boxes, conf = gt.at(17)
    assert ids.shape == (0,) and boxes.shape == (0, 4) and conf.shape == (0,)


def test_load_mot_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "det.txt"
    path.write_text("")
    det = load_mot(path, kind="det")
    assert len(det) == 0 and det.boxes.shape == (0, 4)
    assert det.frame_numbers().shape == (0,)


def test_load_mot_sorts_by_frame(tmp_path: Path) -> None:
    path = tmp_path / "gt.txt"
    path.write_text("3,1,1,1,2,2,1\n1,1,1,1,2,2,1\n3,2,5,5,2,2,1\n1,2,5,5,2,2,1\n")
    gt = load_mot(path)
    np.testing.assert_array_equal(gt.frames, [1, 1, 3, 3])
    np.testing.assert_array_equal(gt.at(3)[0], [1, 2])


def test_load_mot_det_min_score(tmp_path: Path) -> None:
    root = _mot_folder(tmp_path / "seq")
    det = load_mot(root / "det" / "det.txt", kind="det")
    assert len(det) == 3 and not det.ignore.any()
    strong = load_mot(root / "det" / "det.txt", kind="det", min_score=0.5)
    np.testing.assert_allclose(strong.conf, [0.9, 0.8])
    np.testing.assert_array_equal(strong.frames, [1, 2])
    with pytest.raises(InputError):
        load_mot(root / "gt" / "gt.txt", kind="gt", min_score=0.5)


@pytest.mark.parametrize("row", [
    "1,1,10,10,5",                  # fewer than 6 columns
    "1,1,10,ten,5,5,1,-1,-1,-1",    # non-numeric
    "1,1,10,10,0,5,1,-1,-1,-1",     # zero width
    "1,1,10,10,5,-2,1,-1,-1,-1",    # negative height
    "0,1,10,10,5,5,1,-1,-1,-1",     # frame 0
    "1.5,1,10,10,5,5,1,-1,-1,-1",   # fractional frame
])
def test_malformed_mot(tmp_path: Path, row: str) -> None:
    path = tmp_path / "det.txt"
    path.write_text("1,1,10,10,5,5,1,-1,-1,-1\n" + row + "\n")
    with pytest.raises(InputError) as e:
        load_mot(path, kind="det")
    _raises_one_line(e, f"{path}:2")


def test_motwriter_roundtrip(tmp_path: Path) -> None:
    path = tmp_path / "out" / "tracks.txt"
    with MotWriter(path) as w:
        w.write(1, [3, 4], np.array([[0.0, 9.5, 10.0, 20.0], [100.25, 0.0, 5.0, 7.0]]),
                [0.9, 1.0])
        # flushed after each write: the rows are on disk before close
        assert path.read_text().count("\n") == 2
        w.write(2, np.array([], dtype=int), np.zeros((0, 4)), np.zeros(0))
        w.write(3, [3], [[1.0 / 3.0, 2.0, 10.0, 20.0]])
    lines = path.read_text().splitlines()
    assert lines == ["1,3,1,10.5,10,20,0.9,-1,-1,-1",
                     "1,4,101.25,1,5,7,1,-1,-1,-1",
                     "3,3,1.333,3,10,20,1,-1,-1,-1"]
    tracks = load_tracks(path)
    np.testing.assert_array_equal(tracks.frames, [1, 1, 3])
    np.testing.assert_array_equal(tracks.ids, [3, 4, 3])
    np.testing.assert_allclose(tracks.boxes, [[0, 9.5, 10, 20], [100.25, 0, 5, 7],
                                              [0.333, 2, 10, 20]])
    np.testing.assert_allclose(tracks.conf, [0.9, 1.0, 1.0])
    with pytest.raises(InputError):
        w.write(4, [1], [[0, 0, 1, 1]])  # closed


def test_motwriter_rows_are_the_numbers_as_format_numbers_writes_them() -> None:
    """The writer formats a frame's rows in one pass and trims them over the block; each
    number must read as :func:`format_numbers` writes it on its own (trailing zeros and a
    bare point dropped, negative zero as 0, an integer's own zeros kept)."""
    from pgm.io.track_files import _mot_rows, format_numbers

    assert format_numbers([350.0, -0.2, 1200.0], 0) == ["350", "0", "1200"]
    assert format_numbers([100.0, 0.5, -0.0004, 2.0015], 3) == ["100", "0.5", "0", "2.002"]
    rng = np.random.default_rng(0)
    edge = [0.0, -0.0, -0.0004, 0.0005, -0.0005, 1e15, 1e-7, 10.0, 100.5, 0.1, 1.0005,
            2.0015, -0.4, -0.6, 1000.0, 0.25]
    for t in range(400):
        n = int(rng.integers(1, 25))
        values = (rng.uniform(-5, 2000, (n, 5)) if t % 3 == 0 else
                  rng.choice(edge, (n, 5)) if t % 3 == 1 else
                  rng.integers(-100, 100, (n, 5)) / 8.0)
        decimals = int(rng.integers(0, 6)) if t % 5 == 0 else 3
        ids = rng.integers(0, 10**6, n).tolist()
        cols = [format_numbers(values[:, j], decimals) for j in range(5)]
        expected = "".join(f"9,{i},{x},{y},{w},{h},{c},-1,-1,-1\n"
                           for i, x, y, w, h, c in zip(ids, *cols, strict=True))
        assert _mot_rows(9, ids, values, decimals) == expected


def test_motwriter_sorts_rows_that_came_late(tmp_path: Path) -> None:
    """Rows reported late (a gap filled) are put in frame order once the writer is closed,
    each frame's rows in the order they were written; a file written in order is left
    as it is."""
    path = tmp_path / "tracks.txt"
    w = MotWriter(path)
    w.write(1, [1], [[0, 0, 5, 5]])
    w.write(3, [2, 1], [[0, 0, 5, 5], [1, 1, 5, 5]])
    w.write(2, [2], [[2, 2, 5, 5]])  # frame 2 of track 2, reported at frame 3
    w.write(4, [1], [[3, 3, 5, 5]])
    assert not w.in_frame_order
    with pytest.raises(InputError):
        w.sort_by_frame()  # still open
    w.close()
    w.sort_by_frame()
    assert [ln.split(",")[:2] for ln in path.read_text().splitlines()] == \
        [["1", "1"], ["2", "2"], ["3", "2"], ["3", "1"], ["4", "1"]]
    assert not (tmp_path / "tracks.txt.sorting").exists()
    ordered = tmp_path / "ordered.txt"
    with MotWriter(ordered) as w2:
        w2.write(1, [1], [[0, 0, 5, 5]])
        w2.write(2, [1], [[0, 0, 5, 5]])
    before = ordered.stat().st_mtime_ns
    w2.sort_by_frame()
    assert w2.in_frame_order and ordered.stat().st_mtime_ns == before


def test_motwriter_bad_input(tmp_path: Path) -> None:
    with MotWriter(tmp_path / "t.txt") as w:
        with pytest.raises(InputError):
            w.write(1, [1, 2], [[0, 0, 1, 1]])
        with pytest.raises(InputError):
            w.write(0, [1], [[0, 0, 1, 1]])
        with pytest.raises(InputError):
            w.write(1, [1], [[np.nan, 0, 1, 1]])


def test_load_tracks_duplicate_id(tmp_path: Path) -> None:
    path = tmp_path / "tracks.txt"
    path.write_text("1,3,1,1,2,2,1,-1,-1,-1\n1,3,5,5,2,2,1,-1,-1,-1\n")
    with pytest.raises(InputError) as e:
        load_tracks(path)
    _raises_one_line(e, str(path), "track 3")


def test_a_gap_in_the_images_numbering_is_a_warning(tmp_path: Path, caplog) -> None:
    """A file missing from a numbered image folder shifts every later frame against
    annotations kept by frame number: said once, naming the gap; a folder numbered without
    a gap, or not numbered, says nothing."""
    import logging

    image = np.zeros((8, 8, 3), np.uint8)
    for folder, names in (("gap", ["img0001", "img0002", "img0004"]),
                          ("whole", ["img0001", "img0002", "img0003"]),
                          ("named", ["a", "b", "c"])):
        (tmp_path / folder).mkdir()
        for name in names:
            cv2.imwrite(str(tmp_path / folder / f"{name}.png"), image)
    with caplog.at_level(logging.WARNING, logger="pgm"):
        open_source(tmp_path / "gap")
    assert len(caplog.records) == 1
    assert "img0002.png, then img0004.png" in caplog.text and "from frame 3 on" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="pgm"):
        assert len(open_source(tmp_path / "whole")) == len(open_source(tmp_path / "named")) == 3
    assert not caplog.records


def test_natural_key() -> None:
    assert sorted(["a10.png", "a2.png", "a1.png"], key=natural_key) == \
        ["a1.png", "a2.png", "a10.png"]


# --------------------------------------------------------------------------- real data


@pytest.mark.data
def test_real_faceocc1(shared_data: Path) -> None:
    src = open_source(shared_data / "FaceOcc1")
    assert src.layout == "miltrack" and src.gt_format == "miltrack"
    assert len(src) == 888 and src.size == (352, 288)
    n, image = next(iter(src.frames(1, 2)))
    assert n == 1 and image.shape == (288, 352, 3) and image.dtype == np.uint8
    assert np.array_equal(image[..., 0], image[..., 2])  # greyscale PNG -> 3 equal channels
    gt = load_single_gt(src.gt_path, src.gt_format)
    assert len(gt) == 178 and gt.frames[0] == 1 and gt.frames[1] == 6
    np.testing.assert_allclose(gt.boxes[0], [120.5, 71.474, 116, 146])


@pytest.mark.data
def test_real_crossing(shared_data: Path) -> None:
    src = open_source(shared_data / "Crossing")
    assert src.layout == "otb" and src.gt_format == "otb"
    assert len(src) == 120 and src.size == (360, 240)
    gt = load_single_gt(src.gt_path)
    assert len(gt) == 120
    np.testing.assert_array_equal(gt.frames, np.arange(1, 121))
    np.testing.assert_allclose(gt.boxes[0], [204, 150, 17, 50])  # file: 205,151,17,50


@pytest.mark.data
def test_real_pets_mot(shared_data: Path) -> None:
    src = open_source(shared_data / "PETS09-S2L1")
    assert src.layout == "mot" and src.fps == 7.0 and len(src) == 240
    assert src.size == (768, 576)
    gt = load_mot(src.gt_path, kind="gt")
    assert len(gt) == 1474 and int(gt.ignore.sum()) == 170
    assert len(np.unique(gt.ids)) == 10
    det = load_mot(src.det_path, kind="det")
    assert len(det) == 1730


@pytest.mark.data
def test_real_pets_video(shared_data: Path) -> None:
    src = open_source(shared_data / "PETS09-S2L1-video" / "vtest.avi")
    assert isinstance(src, VideoSource) and src.layout == "video"
    assert len(src) == 795 and src.size == (768, 576)
    first3 = list(src.frames(1, 4))
    assert [n for n, _ in first3] == [1, 2, 3]
    assert all(im.shape == (576, 768, 3) and im.dtype == np.uint8 for _, im in first3)
    assert src.gt_path is not None and src.gt_path.name == "gt.txt"
    assert src.fps == pytest.approx(10.0)  # the container's rate; MOT15 says 7
    folder = open_source(shared_data / "PETS09-S2L1-video")
    assert isinstance(folder, VideoSource) and folder.layout == "mot"
    assert folder.fps == 7.0 and len(folder) == 795


def test_mot16_sequence_ground_truth_follows_the_protocol(shared_data):
    """MOT16-11: 3349 pedestrian rows with consider=1 are scored, the 284 distractor
    (class 8) rows are ignore regions and the 385 occluder (class 9) rows are neither
    (counts read off the file with awk)."""
    from pgm.io.annotations import load_mot

    gt = load_mot(shared_data / "MOT16-11" / "gt" / "gt.txt", kind="gt")
    assert gt.fmt == "mot16"
    assert int(gt.scored.sum()) == 3349 and int(gt.ignore.sum()) == 284
    assert int((gt.classes == 9).sum()) == 385 and not np.any(gt.scored & (gt.classes != 1))
    pets = load_mot(shared_data / "PETS09-S2L1" / "gt" / "gt.txt", kind="gt")
    assert pets.fmt == "mot15"
