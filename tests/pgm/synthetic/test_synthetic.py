"""Synthetic scenes: determinism, exact ground truth, occlusion layouts, file writers."""

from __future__ import annotations

import configparser

import cv2
import numpy as np
import pytest

from pgm.synthetic import (
    ObjectSpec,
    OccluderSpec,
    Scene,
    demo_scene,
    multi_target_scene,
    part_occlusion_scene,
)


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """(length, first index) of the longest run of True."""
    best, best_start, run, start = 0, -1, 0, 0
    for i, m in enumerate(mask):
        if m:
            if run == 0:
                start = i
            run += 1
            if run > best:
                best, best_start = run, start
        else:
            run = 0
    return best, best_start


def _inner(box: np.ndarray, n_bands: int, k: int, margin: int = 3):
    """Integer row/column slices well inside band ``k`` of a top-left box."""
    x, y, w, h = box
    top, bottom = y + h * k / n_bands, y + h * (k + 1) / n_bands
    return (slice(int(np.ceil(top)) + margin, int(np.floor(bottom)) - margin),
            slice(int(np.ceil(x)) + margin, int(np.floor(x + w)) - margin))


@pytest.fixture(scope="module")
def demo():
    return demo_scene(seed=0)


@pytest.fixture(scope="module")
def part2():
    return part_occlusion_scene(seed=0, n_bands=2)


def test_same_seed_same_frames_and_different_seed_different_noise():
    a = part_occlusion_scene(seed=3, n_frames=6)
    b = part_occlusion_scene(seed=3, n_frames=6)
    c = part_occlusion_scene(seed=4, n_frames=6)
    assert all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames, strict=True))
    assert not any(np.array_equal(x, y) for x, y in zip(a.frames, c.frames, strict=True))
    # the geometry does not depend on the seed
    np.testing.assert_array_equal(a.gt[0].boxes, c.gt[0].boxes)
    # consecutive frames of a static part of the scene differ by per-frame noise only
    d = np.abs(a.frames[0].astype(int) - a.frames[1].astype(int))[:40, :40]
    assert 0 < d.mean() < 6


def test_render_and_stream_agree_and_global_state_untouched():
    scene = demo_scene(seed=0, n_frames=1).scene
    np.random.seed(123)  # noqa: NPY002 - checking that the global state is left alone
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    seq = scene.render(np.random.default_rng(7), 4)
    streamed = list(scene.frames(np.random.default_rng(7), 4))
    assert np.array_equal(np.random.get_state()[1], before)  # noqa: NPY002
    assert all(np.array_equal(x, y) for x, y in zip(seq.frames, streamed, strict=True))
    f = seq.frames[0]
    assert f.dtype == np.uint8 and f.shape == (240, 320, 3)


def test_band_colours_are_where_the_ground_truth_says(part2):
    colours = np.array(part2.scene.objects[0].colors)
    for f in (1, 10, 45, 79):
        box = part2.box(0, f)
        img = part2.frames[f - 1].astype(float)
        vis = part2.band_visibility(0, 2)[f - 1]
        for k in range(2):
            if vis[k] < 1:
                continue
            rows, cols = _inner(box, 2, k)
            mean = img[rows, cols].reshape(-1, 3).mean(axis=0)
            assert np.abs(mean - colours[k]).max() < 12, (f, k, mean)
        # just outside the box: background, far from both band colours
        x, y, w, h = box
        bg = img[int(y) + 5:int(y + h) - 5, int(x + w) + 4:int(x + w) + 8].reshape(-1, 3)
        assert np.abs(bg.mean(axis=0) - colours).max(axis=1).min() > 60


def test_hidden_band_pixels_show_the_occluder(part2):
    bv = part2.band_visibility(0, 2)
    f = int(np.flatnonzero(bv[:, 1] == 0)[0]) + 1
    rows, cols = _inner(part2.box(0, f), 2, 1)
    mean = part2.frames[f - 1][rows, cols].reshape(-1, 3).mean(axis=0)
    blue = np.array(part2.scene.objects[0].colors[1])
    assert np.abs(mean - blue).max() > 80  # grey magazine, not the blue band
    assert np.ptp(mean) < 25  # unsaturated


@pytest.mark.parametrize("n_bands,hidden", [(2, 1), (2, 0), (3, 0), (3, 1), (3, 2)])
def test_part_occlusion_hides_exactly_one_band(n_bands, hidden):
    seq = part_occlusion_scene(seed=1, n_frames=80, n_bands=n_bands, hidden_band=hidden)
    bv = seq.band_visibility(0, n_bands)
    assert bv.shape == (80, n_bands)
    length, start = _longest_run(bv[:, hidden] == 0)
    assert length >= 15
    assert (start + 1, length) == (33, 25)  # documented layout: frames 33-57
    others = np.delete(bv, hidden, axis=1)
    assert np.all(others == 1.0)
    assert np.all(bv[:17] == 1.0) and np.all(bv[72:] == 1.0)  # clear at both ends
    # the whole-box visibility is the mean of the bands
    np.testing.assert_allclose(seq.visibility[0], bv.mean(axis=1), atol=1e-12)


def test_part_occlusion_non_contiguous_bands():
    seq = part_occlusion_scene(seed=0, n_frames=60, n_bands=3, hidden_band=[0, 2])
    bv = seq.band_visibility(0, 3)
    assert _longest_run((bv[:, 0] == 0) & (bv[:, 2] == 0))[0] >= 15
    assert np.all(bv[:, 1] == 1.0)


def test_demo_lower_half_hidden_upper_half_visible(demo):
    assert demo.n_frames == 90 and demo.n_objects == 2
    bv = demo.band_visibility(0, 2)
    assert np.all(bv[:, 0] == 1.0)
    length, start = _longest_run(bv[:, 1] == 0)
    assert length >= 15 and (start + 1, length) == (48, 22)
    assert np.all(bv[:34, 1] == 1.0)
    # 3 bands of the same box: the occluder edge is at 1/2 of the height
    bv3 = demo.band_visibility(0, 3)
    assert np.all(bv3[:, 0] == 1.0)
    assert np.all(bv3[47:69, 2] == 0.0)
    np.testing.assert_allclose(bv3[47:69, 1], 0.5)
    # the distractor is never hidden
    assert np.all(demo.visibility[1] == 1.0)
    # the upper band is red in a fully-hidden frame, the lower band shows the page
    f = start + 1 + 5
    img = demo.frames[f - 1].astype(float)
    red = img[_inner(demo.box(0, f), 2, 0)].reshape(-1, 3).mean(axis=0)
    assert np.abs(red - np.array(demo.scene.objects[0].colors[0])).max() < 12


def test_scene_band_visibility_function_matches_sequence(demo):
    for f in (1, 50, 75):
        np.testing.assert_array_equal(demo.scene.band_visibility(0, f, 2),
                                      demo.band_visibility(0, 2)[f - 1])


def test_subpixel_box_is_blended_by_area():
    obj = ObjectSpec(box=(10.25, 20.5, 8.0, 6.0), colors=[(200, 200, 200)], texture=0,
                     noise=0)
    seq = Scene([obj], background=(0, 0, 0), background_contrast=0, sensor_noise=0,
                size=(40, 40)).render(np.random.default_rng(0), 1)
    img = seq.frames[0][..., 0].astype(float)
    assert img[22, 10] == pytest.approx(150, abs=1)  # 3/4 of column 10 covered
    assert img[20, 12] == pytest.approx(100, abs=1)  # half of row 20 covered
    assert img[23, 14] == 200 and img[23, 19] == 0
    assert img.sum() == pytest.approx(200 * 8 * 6, abs=3)


def test_multi_target_births_deaths_and_detections():
    seq = multi_target_scene(seed=0, n_frames=100)
    assert seq.width == 640 and seq.height == 480 and seq.n_objects == 6
    first = [int(t.frames[0]) for t in seq.gt]
    last = [int(t.frames[-1]) for t in seq.gt]
    assert first == [1, 1, 13, 30, 45, 21]
    assert last == [100, 89, 100, 84, 100, 100]
    counts = [len(seq.boxes_at(f)[0]) for f in range(1, 101)]
    assert min(counts) >= 2 and max(counts) >= 5
    # object 5 grows
    assert seq.gt[4].boxes[-1, 3] > 1.2 * seq.gt[4].boxes[0, 3]
    # crossings: some object is partly hidden by another at some frame
    assert np.any((seq.visibility > 0) & (seq.visibility < 1))
    dets = seq.detections(np.random.default_rng(0), p_detect=0.8, sigma=1.5,
                          clutter_rate=2.0)
    true = dets[dets[:, 6] > 0]
    clutter = dets[dets[:, 6] < 0]
    n_visible = int((seq.visibility >= 0.3).sum())
    assert 0.65 * n_visible < len(true) < 0.95 * n_visible
    assert 120 < len(clutter) < 290
    assert np.all(np.diff(dets[:, 0]) >= 0)
    for d in true[:50]:
        b = seq.box(int(d[6]) - 1, int(d[0]))
        assert np.abs(d[1:5] - b).max() < 10
    again = seq.detections(np.random.default_rng(0), p_detect=0.8, sigma=1.5,
                           clutter_rate=2.0)
    np.testing.assert_array_equal(dets, again)


def test_write_otb_round_trip(tmp_path):
    part2 = part_occlusion_scene(seed=0, n_frames=12)
    folder = part2.write_otb(tmp_path / "otb")
    lines = (folder / "groundtruth_rect.txt").read_text().splitlines()
    assert len(lines) == part2.n_frames
    boxes = np.array([[float(v) for v in line.split(",")] for line in lines])
    np.testing.assert_allclose(boxes[:, :2] - 1, part2.gt[0].boxes[:, :2], atol=1e-6)
    np.testing.assert_allclose(boxes[:, 2:], part2.gt[0].boxes[:, 2:], atol=1e-6)
    files = sorted((folder / "img").glob("*.png"))
    assert [p.name for p in files[:2]] == ["0001.png", "0002.png"]
    assert len(files) == part2.n_frames
    assert np.array_equal(cv2.imread(str(files[4])), part2.frames[4])


def test_write_otb_marks_absent_frames(tmp_path):
    obj = ObjectSpec(box=(5, 5, 10, 10), start=3, end=5, noise=0)
    seq = Scene([obj], size=(40, 30)).render(np.random.default_rng(0), 6)
    lines = (seq.write_otb(tmp_path) / "groundtruth_rect.txt").read_text().splitlines()
    assert lines[0] == "NaN,NaN,NaN,NaN" and lines[5] == "NaN,NaN,NaN,NaN"
    assert lines[2] == "6,6,10,10"


def test_write_mot_round_trip(tmp_path):
    seq = multi_target_scene(seed=2, n_frames=12)
    folder = seq.write_mot(tmp_path / "MOT-synth", rng=5, p_detect=0.9, sigma=2.0,
                           clutter_rate=1.0)
    ini = configparser.ConfigParser()
    ini.read(folder / "seqinfo.ini")
    info = ini["Sequence"]
    assert info["imDir"] == "img1" and info["imExt"] == ".png"
    assert int(info["seqLength"]) == 12 and float(info["frameRate"]) == 30
    assert (int(info["imWidth"]), int(info["imHeight"])) == (640, 480)
    imgs = sorted((folder / "img1").glob("*.png"))
    assert len(imgs) == 12 and imgs[0].name == "000001.png"
    assert np.array_equal(cv2.imread(str(imgs[-1])), seq.frames[-1])

    gt = np.loadtxt(folder / "gt" / "gt.txt", delimiter=",", ndmin=2)
    assert gt.shape[1] == 10
    assert np.all(gt[:, 6] == 1) and np.all(gt[:, 7:] == -1)
    assert len(gt) == sum(len(t.frames) for t in seq.gt)
    for row in gt:
        b = seq.box(int(row[1]) - 1, int(row[0]))
        np.testing.assert_allclose(row[2:4] - 1, b[:2], atol=1e-6)
        np.testing.assert_allclose(row[4:6], b[2:], atol=1e-6)

    det = np.loadtxt(folder / "det" / "det.txt", delimiter=",", ndmin=2)
    ref = seq.detections(np.random.default_rng(5), p_detect=0.9, sigma=2.0, clutter_rate=1.0)
    assert det.shape == (len(ref), 10)
    assert np.all(det[:, 1] == -1) and np.all(det[:, 7:] == -1)
    np.testing.assert_array_equal(det[:, 0], ref[:, 0])
    np.testing.assert_allclose(det[:, 2:4] - 1, ref[:, 1:3], atol=1e-5)
    np.testing.assert_allclose(det[:, 4:7], ref[:, 3:6], atol=1e-5)
    assert np.all((det[:, 6] >= 0) & (det[:, 6] <= 1))


@pytest.mark.parametrize("build,message", [
    (lambda: Scene([]), "at least one object"),
    (lambda: ObjectSpec(box=(0, 0, 0, 10)), "positive width and height"),
    (lambda: ObjectSpec(box=(0, 0, 10, -1)), "positive width and height"),
    (lambda: ObjectSpec(box=(0, 0, 10, 10), colors=[]), "at least one"),
    (lambda: ObjectSpec(box=(0, 0, 10, 10), start=0), "start"),
    (lambda: OccluderSpec(box=(0, 0, 5, 0)), "positive width and height"),
    (lambda: demo_scene(n_frames=0), "n_frames"),
    (lambda: part_occlusion_scene(n_frames=-3), "n_frames"),
    (lambda: part_occlusion_scene(n_bands=2, hidden_band=2), "hidden_band"),
    (lambda: multi_target_scene(n_objects=7), "n_objects"),
])
def test_invalid_input_raises_one_line_value_error(build, message):
    with pytest.raises(ValueError, match=message) as info:
        build()
    assert "\n" not in str(info.value)


def test_render_rejects_bad_n_frames():
    scene = Scene([ObjectSpec(box=(1, 1, 5, 5))], size=(20, 20))
    with pytest.raises(ValueError, match="n_frames"):
        scene.render(np.random.default_rng(0), 0)
    with pytest.raises(ValueError, match="object index"):
        scene.band_visibility(1, 1, 2)


def test_desk_scene_box_bounds_the_cube_and_the_video_is_reproducible():
    """The desk scene's box is the cube's bounding box (on a plain desk, the box's
    outermost rows and columns touch the cube and a band outside is the desk); the same
    seed renders the same video, a shorter one its start, and the cube stays in view."""
    from pgm.synthetic.scenes import desk_scene

    a, b = desk_scene(3, 40), desk_scene(3, 40)
    assert all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames, strict=True))
    np.testing.assert_array_equal(a.boxes, b.boxes)
    assert not np.array_equal(desk_scene(4, 40).frames[0], a.frames[0])
    longer = desk_scene(3, 90)  # a shorter video is the start of a longer one
    np.testing.assert_array_equal(longer.boxes[:40], a.boxes)
    assert all(np.array_equal(x, y) for x, y in zip(longer.frames, a.frames, strict=False))
    boxes = desk_scene(0, 600).boxes
    assert np.all(boxes[:, :2] >= 0) and np.all(boxes[:, 0] + boxes[:, 2] <= 320)
    assert np.all(boxes[:, 1] + boxes[:, 3] <= 240)
    # a plain desk (no texture): the cube is what differs from the desk's lit grey
    plain = desk_scene(5, 30, background=0.0)
    for img, (x, y, w, h) in zip(plain.frames[::7], plain.boxes[::7], strict=True):
        g = img[..., 0].astype(float)
        x0, y0, x1, y1 = int(np.floor(x)), int(np.floor(y)), int(np.ceil(x + w)), int(np.ceil(y + h))
        inside = g[y0:y1, x0:x1]
        ring = np.concatenate([g[max(y0 - 6, 0):max(y0 - 2, 0), x0:x1].ravel(),
                               g[y1 + 2:y1 + 6, x0:x1].ravel()])
        # sensor noise 3 grey levels; the cube's texture varies by tens
        assert inside.std() > 5 * ring.std() or ring.size == 0
        # the box is tight: each side's outermost row / column still touches the cube
        rows = np.abs(inside - np.median(ring)) > 12
        assert rows[:3].any() and rows[-3:].any() and rows[:, :3].any() and rows[:, -3:].any()
