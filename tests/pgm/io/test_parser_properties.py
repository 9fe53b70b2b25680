"""Property tests (Hypothesis) of every parser of user files, and of boxes at the image
border and of sub-pixel size (issue 12).

The contract: a parser either returns a well-formed result or raises ``ValueError``
(:class:`~pgm.core.errors.InputError`) — never another exception, never a silent NaN.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pgm.core.errors import InputError

FAST = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

# text that looks like annotation files: numbers, separators, junk
_token = st.one_of(
    st.integers(-5, 300).map(str),
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(lambda v: f"{v:g}"),
    st.sampled_from(["", "nan", "NaN", "inf", "-inf", "1e300", "-0", "x", "1,2", "\t", " "]),
)
_line = st.lists(_token, min_size=0, max_size=11).flatmap(
    lambda toks: st.sampled_from([",", " ", "\t", ", "]).map(lambda sep: sep.join(toks)))
_text = st.lists(_line, max_size=8).map("\n".join)


def _write(tmp: Path, name: str, text: str | bytes) -> Path:
    p = tmp / name
    p.parent.mkdir(parents=True, exist_ok=True)
    (p.write_bytes if isinstance(text, bytes) else p.write_text)(text)
    return p


@FAST
@given(text=_text, kind=st.sampled_from(["gt", "det"]))
def test_mot_parser_returns_finite_rows_or_input_error(tmp_path_factory, text, kind):
    from pgm.io.annotations import load_mot

    p = _write(tmp_path_factory.mktemp("mot"), "gt.txt", text)
    try:
        t = load_mot(p, kind=kind)
    except InputError as exc:
        assert "\n" not in str(exc) and str(p) in str(exc)
        return
    assert np.all(np.isfinite(t.boxes)) and np.all(t.boxes[:, 2:] > 0)
    assert np.all(np.isfinite(t.conf)) and np.all(t.frames >= 1)


@FAST
@given(text=_text, fmt=st.sampled_from(["otb", "miltrack", "auto"]))
def test_single_object_parsers_return_boxes_or_input_error(tmp_path_factory, text, fmt):
    from pgm.io.annotations import load_single_gt

    name = {"otb": "groundtruth_rect.txt", "miltrack": "seq_gt.txt", "auto": "boxes.txt"}[fmt]
    p = _write(tmp_path_factory.mktemp("gt"), name, text)
    try:
        gt = load_single_gt(p, fmt)
    except InputError as exc:
        assert "\n" not in str(exc)
        return
    assert len(gt) > 0 and np.all(np.isfinite(gt.boxes)) and np.all(gt.boxes[:, 2:] > 0)
    assert np.all(np.diff(gt.frames) > 0)


@FAST
@given(rows=st.lists(st.tuples(st.integers(1, 50), st.integers(0, 9),
                               st.floats(-50, 500), st.floats(-50, 500),
                               st.floats(0.01, 300), st.floats(0.01, 300),
                               st.floats(0, 1)), min_size=1, max_size=20,
                     unique_by=lambda r: (r[0], r[1])))
def test_mot_writer_round_trip(tmp_path_factory, rows):
    from pgm.io.annotations import MotWriter, load_tracks

    p = tmp_path_factory.mktemp("rt") / "tracks.txt"
    rows = sorted(rows, key=lambda r: r[0])
    a = np.array(rows, dtype=float)
    assume(np.all(np.round(a[:, 4:6], 3) > 0))
    with MotWriter(p) as w:
        w.write_rows(a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2:6], a[:, 6])
    t = load_tracks(p)
    assert len(t) == len(rows)
    np.testing.assert_allclose(np.sort(t.boxes[:, 0]), np.sort(a[:, 2]), atol=6e-4)


_ini_value = st.one_of(st.integers(-3, 10**6).map(str),
                       st.floats(allow_nan=True, allow_infinity=True).map(repr),
                       st.sampled_from(["", "abc", "1e300", "1e-300", "30", "0", "-1",
                                        ".png", "png", "img1"]))


@FAST
@given(keys=st.dictionaries(st.sampled_from(["name", "imDir", "frameRate", "seqLength",
                                             "imExt", "imWidth"]), _ini_value),
       section=st.sampled_from(["[Sequence]", "[sequence]", "[Other]", ""]),
       junk=st.sampled_from(["", "=\n", "[broken\n", "x"]))
def test_seqinfo_parser(tmp_path_factory, keys, section, junk):
    import cv2

    from pgm.io.video import MAX_FPS, MIN_FPS, open_source

    d = tmp_path_factory.mktemp("seqinfo")
    (d / "img1").mkdir()
    cv2.imwrite(str(d / "img1" / "000001.png"), np.zeros((4, 4, 3), np.uint8))
    body = "\n".join(f"{k}={v}" for k, v in keys.items())
    _write(d, "seqinfo.ini", f"{section}\n{body}\n{junk}")
    try:
        src = open_source(d)
        frames = list(src.frames())
    except InputError as exc:
        assert "\n" not in str(exc)
        return
    assert MIN_FPS <= src.fps <= MAX_FPS
    assert len(frames) == len(src) >= 1


def _good_model() -> dict:
    from pgm.models import colour_pf

    g = colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 10, 10)))
    return json.loads(json.dumps(g.to_dict()))


_json = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                               st.floats(allow_nan=False), st.text(max_size=8)),
                     lambda c: st.lists(c, max_size=4) | st.dictionaries(
                         st.text(max_size=8), c, max_size=4), max_leaves=12)


@FAST
@given(data=st.data())
def test_model_json_loader(tmp_path_factory, data):
    """Random JSON, and a saved model with one value replaced anywhere in it, load as a
    graph or fail with a one-line InputError naming the file (never a TypeError...)."""
    from pgm.app.cli import load_model_file

    d = tmp_path_factory.mktemp("model")
    model = _good_model()
    if data.draw(st.booleans()):
        doc = data.draw(_json)
    else:
        doc = model
        node = doc
        for _ in range(data.draw(st.integers(0, 4))):
            if isinstance(node, dict) and node:
                key = data.draw(st.sampled_from(sorted(node)))
            elif isinstance(node, list) and node:
                key = data.draw(st.integers(0, len(node) - 1))
            else:
                break
            if not isinstance(node[key], (dict, list)) or data.draw(st.booleans()):
                node[key] = data.draw(_json)
                break
            node = node[key]
    p = _write(d, "model.json", json.dumps(doc))
    try:
        load_model_file(p)
    except InputError as exc:
        assert "\n" not in str(exc)


@pytest.fixture(scope="module")
def good_dbn(tmp_path_factory):
    from pgm.observation.appearance.features import PatchFeatures

    d = PatchFeatures().dim
    rng = np.random.default_rng(0)
    weights = [rng.normal(size=(d, 4)), np.zeros(4), rng.normal(size=(4, 3)), np.zeros(3),
               np.zeros((3, 1)), np.zeros(1)]
    header = {"format": "pgm-dbn-v1", "hidden": [4, 3], "platt": [1.0, 0.0], "prior": 0.3,
              "features": PatchFeatures().to_dict()}
    return header, weights


@FAST
@given(data=st.data())
def test_dbn_loader(tmp_path_factory, good_dbn, data):
    """Random bytes, and a good DBN file with a header key replaced or removed or a weight
    reshaped or poisoned, load or fail with an InputError naming the file."""
    from pgm.observation.appearance.dbn import DBN

    d = tmp_path_factory.mktemp("dbn")
    p = d / "net.npz"
    header, weights = dict(good_dbn[0]), [w.copy() for w in good_dbn[1]]
    what = data.draw(st.sampled_from(["bytes", "header", "drop", "shape", "poison", "good"]))
    if what == "bytes":
        p.write_bytes(data.draw(st.binary(max_size=64)))
    else:
        if what == "header":
            header[data.draw(st.sampled_from(sorted(header)))] = data.draw(_json)
        elif what == "drop":
            del header[data.draw(st.sampled_from(sorted(header)))]
        elif what == "shape":
            k = data.draw(st.integers(0, 5))
            weights[k] = np.zeros(data.draw(st.lists(st.integers(0, 3), max_size=3)))
        elif what == "poison":
            k = data.draw(st.integers(0, 5))
            weights[k] = weights[k].copy()
            weights[k].flat[0] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
        np.savez(p, header=np.array(json.dumps(header)),
                 **{f"w{k}": w for k, w in enumerate(weights)})
    try:
        net = DBN.load(p)
    except InputError as exc:
        assert "\n" not in str(exc) and str(p) in str(exc)
        assert what != "good"
        return
    assert all(np.all(np.isfinite(w)) for w in net.weights_)
    x = np.random.default_rng(0).random((3, net.weights_[0].shape[0]))
    assert np.all(np.isfinite(net.log_ratio(x)))


# -- boxes at the image border and of sub-pixel size ---------------------------------
_IMAGE = np.random.default_rng(1).integers(0, 256, (48, 64, 3), dtype=np.uint8)


@settings(max_examples=40, deadline=None)
@given(cue=st.sampled_from(["colour", "contrast", "fragments", "rings", "template",
                            "gradient", "cf"]),
       x=st.floats(-0.45, 1.45), y=st.floats(-0.45, 1.45),
       w=st.floats(0.05, 30), h=st.floats(0.05, 30), grey=st.booleans())
def test_boxes_at_the_border_and_sub_pixel(cue, x, y, w, h, grey):
    """A model on a box anywhere on or across the image border, down to a twentieth of a
    pixel, either refuses it with a one-line ValueError or tracks with finite estimates."""
    from pgm.core.frame import FrameContext
    from pgm.inference.engine import Engine
    from pgm.models import colour_pf

    image = np.repeat(_IMAGE[:, :, :1], 3, axis=2) if grey else _IMAGE
    box = (x * 64, y * 48, w, h)
    try:
        graph = colour_pf.build_graph(colour_pf.Params(init_box=box, appearance=cue,
                                                       num_particles=20))
        engine = Engine(graph, np.random.default_rng(0))
        for k in (1, 2, 3):
            record = engine.step(FrameContext(k, image))
    except ValueError as exc:  # the API's contract for bad input
        assert "\n" not in str(exc)
        return
    est = record.estimates["object"]
    assert np.all(np.isfinite(est))
