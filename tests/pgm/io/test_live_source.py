"""Live sources: a stream URL is read once, as it comes; a missing camera is one line."""

import cv2
import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.io.video import LiveSource, is_live, open_source


def _video(path, n=6, size=(64, 48)):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, size)
    for k in range(n):
        img = np.full((size[1], size[0], 3), 20 * k, np.uint8)
        w.write(img)
    w.release()
    return path


def test_a_stream_url_is_read_once_as_it_comes(tmp_path):
    url = "file://" + str(_video(tmp_path / "v.avi"))
    assert is_live(url) and is_live("0") and not is_live(str(tmp_path))
    src = open_source(url)
    assert isinstance(src, LiveSource) and src.size == (64, 48)
    assert src._known_length() is None and src.layout == "live"
    frames = list(src.frames())
    assert [k for k, _ in frames] == [1, 2, 3, 4, 5, 6]
    assert frames[3][1].mean() > frames[1][1].mean()  # the frames in order
    with pytest.raises(InputError, match="read once"):
        list(src.frames())


def test_a_missing_camera_or_stream_is_a_clear_error(tmp_path):
    with pytest.raises(InputError, match="cannot open camera 97"):
        open_source("97")
    with pytest.raises(InputError, match="cannot open stream"):
        open_source("file://" + str(tmp_path / "nothing.avi"))


def test_track_multi_takes_any_iterable_of_frames(tmp_path):
    from pgm.app.runner import track_multi
    from pgm.models import multi_pf
    from pgm.observation.detections import Detections
    from pgm.synthetic import multi_target_scene

    seq = multi_target_scene(seed=0, n_frames=6, n_objects=2)

    def detector(number, image):
        ids, boxes = seq.boxes_at(number)
        return Detections(boxes, np.ones(len(boxes)))

    gen = (img for img in seq.frames)  # plain images, numbered from 1
    r = track_multi(gen, multi_pf.build_graph(multi_pf.Params(num_particles=20)), detector,
                    rng=np.random.default_rng(0), out_dir=tmp_path / "out", progress=False,
                    write_video=False)
    assert r.n_frames == 6 and (tmp_path / "out" / "tracks.txt").is_file()
    assert len(set(r.table.ids.tolist())) == 2  # both people confirmed and kept
    with pytest.raises(InputError, match="empty"):
        track_multi(iter([]), multi_pf.build_graph(), detector, rng=np.random.default_rng(0))


def test_version_flag(capsys):
    from pgm import __version__
    from pgm.app.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and __version__ in capsys.readouterr().out
