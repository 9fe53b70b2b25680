"""``pgm report``: the HTML page over one run and over a folder of runs, and bad input."""

import base64
import json
import shutil
from html.parser import HTMLParser

import pytest
from cli_run import run_cli

from pgm.app.cli import main
from pgm.app.report import FILES_DIR, find_runs, group_runs, load_run, write_report
from pgm.core.errors import InputError
from pgm.synthetic import demo_scene, multi_target_scene


class _Page(HTMLParser):
    """What the tests look at: ids, images, headings, links and tags used."""

    def __init__(self):
        super().__init__()
        self.ids, self.images, self.tags, self.urls = set(), [], set(), []
        self.h2, self._in_h2 = [], False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.add(tag)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "img":
            self.images.append(a)
        for key in ("src", "href"):
            if key in a:
                self.urls.append(a[key])
        self._in_h2 = tag == "h2"

    def handle_endtag(self, tag):
        if tag == "h2":
            self._in_h2 = False

    def handle_data(self, data):
        if self._in_h2:
            self.h2.append(data.strip())


def _parse(path):
    text = path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    page.close()
    return text, page


def _check_self_contained(text, page, folder):
    assert text.startswith("<!DOCTYPE html>")
    assert not page.tags & {"script", "link", "iframe", "object", "embed"}
    assert page.images
    for img in page.images:
        src = img["src"]
        assert src.startswith("data:image/png;base64,"), src[:40]
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
        assert img.get("alt")
        # the same image is written beside the page
        assert (folder / img["data-file"]).read_bytes() == base64.b64decode(src.split(",")[1])
    for url in page.urls:  # only in-page anchors and embedded images
        assert url.startswith(("#", "data:image/png;base64,")), url
    assert "http://" not in text and "https://" not in text



@pytest.fixture(scope="module")
def sequences(tmp_path_factory):
    """A 16-frame OTB scene (one walker) and a 20-frame MOT scene (three people)."""
    d = tmp_path_factory.mktemp("seqs")
    otb = demo_scene(seed=0, n_frames=16).write_otb(d / "walker")
    mot = multi_target_scene(seed=0, n_frames=20, n_objects=3).write_mot(
        d / "crowd", rng=0, sigma=1.0, clutter_rate=0.5)
    return otb, mot


def _track(out, source, model, seed, *extra):
    code = main(["track", str(source), "--model", model, "--out", str(out), "--seed",
                 str(seed), "--quiet", "--no-video", *map(str, extra)])
    assert code == 0


@pytest.fixture(scope="module")
def bench_dir(sequences, tmp_path_factory):
    """``runs/<seq>/<model>/<seed>/`` as an experiment writes it: colour-pf with two
    seeds and single-object with one on the walker, phd with two seeds on the crowd,
    and one unfinished run."""
    otb, mot = sequences
    root = tmp_path_factory.mktemp("bench")
    runs = root / "runs"
    for seed in (0, 1):
        _track(runs / "walker" / "colour-pf" / str(seed), otb, "colour-pf", seed,
               "--particles", 30)
        _track(runs / "crowd" / "phd" / str(seed), mot, "phd", seed)
    _track(runs / "walker" / "single-object" / "0", otb, "single-object", 0,
           "--particles", 30)
    broken = runs / "crowd" / "phd" / "2"
    shutil.copytree(runs / "crowd" / "phd" / "0", broken)
    (broken / "metrics.json").unlink()
    info = json.loads((broken / "run.json").read_text())
    (broken / "run.json").write_text(json.dumps({**info, "complete": False,
                                                 "stopped": "interrupted by SIGTERM"}))
    return root


def test_report_on_one_single_object_run(sequences, tmp_path, capsys):
    otb, _ = sequences
    out = tmp_path / "run"
    _track(out, otb, "colour-pf", 0, "--particles", 30)
    code, stdout, err = run_cli(capsys, "report", out)
    assert code == 0, err
    assert "report.html" in stdout
    text, page = _parse(out / "report.html")
    _check_self_contained(text, page, out)
    assert {"summary", "single-object", "otb-overall", "otb-walker", "fps", "models",
            "metrics", "runs"} <= page.ids
    assert "multi-target" not in page.ids
    # success, precision, fps and the graph drawing
    files = sorted(p.name for p in (out / FILES_DIR).glob("*.png"))
    assert files == ["fps.png", "graph-colour-pf.png", "otb-overall.png", "otb-walker.png"]
    assert len(page.images) == len(files)
    assert "success AUC" in text and "precision @ 20 px" in text
    metrics = json.loads((out / "metrics.json").read_text())
    assert f"{metrics['success_auc']:.4g}" in text  # the table holds the stored value


@pytest.mark.slow
def test_report_on_a_folder_of_runs(bench_dir, capsys):
    path = write_report(bench_dir)
    assert path == bench_dir / "report.html"
    text, page = _parse(path)
    _check_self_contained(text, page, bench_dir)
    assert {"summary", "single-object", "otb-overall", "otb-walker", "calibration",
            "multi-target", "mot-crowd", "ospa-crowd", "fps", "models", "metrics",
            "metrics-crowd", "metrics-walker", "runs"} <= page.ids
    assert "Multi-target tracking" in page.h2 and "Single-object tracking" in page.h2
    names = {p.name for p in (bench_dir / FILES_DIR).glob("*.png")}
    assert {"otb-walker.png", "otb-overall.png", "mot-crowd.png", "ospa-crowd.png",
            "fps.png", "graph-phd.png", "graph-colour-pf.png",
            "graph-single-object.png", "calibration.png"} <= names
    # seeds are averaged: mean ± std, n=2 in the tables' headings
    assert "colour-pf (n=2)" in text and "phd (n=2)" in text and "±" in text
    # the unfinished run is listed as left out, not averaged
    assert "1 unfinished run(s)" in text and "interrupted by SIGTERM" in text
    # a second report replaces the first one's images
    (bench_dir / FILES_DIR / "stale.png").write_bytes(b"x")
    write_report(bench_dir, title="Second")
    assert not (bench_dir / FILES_DIR / "stale.png").exists()
    assert "<title>Second</title>" in (bench_dir / "report.html").read_text()


def _scored_run(folder, sequence, values, ious):
    """A run folder with a model's per-frame confidence and IoU, as ``pgm track`` writes."""
    folder.mkdir(parents=True)
    frames = list(range(1, len(values) + 1))
    (folder / "run.json").write_text(json.dumps({"model": "m", "source": f"/data/{sequence}",
                                                 "complete": True}))
    (folder / "metrics.json").write_text(json.dumps({
        "frames": frames, "ious": ious, "success_auc": 0.5,
        "confidence": {"frames": frames, "values": values}}))


@pytest.mark.slow
def test_confidence_calibration_weights_every_sequence_equally(tmp_path, bench_dir):
    """Hand-worked: sequence A, four frames at confidence 0.9, all hits; sequence B,
    one frame at 0.9, a miss (its IoU is NaN: no box). Pooled with each sequence
    weighted equally the hit rate is 1/2 and the ECE |0.9 - 0.5| = 0.4 (pooled per frame
    it would be 0.1); per sequence the ECEs are 0.1 and 0.9, mean 0.5. A second seed
    of A with the same frames leaves the weighting of the sequences unchanged."""
    root = tmp_path / "runs"
    _scored_run(root / "A" / "m" / "0", "A", [0.9] * 4, [0.8] * 4)
    _scored_run(root / "A" / "m" / "1", "A", [0.9] * 4, [0.7] * 4)
    _scored_run(root / "B" / "m" / "0", "B", [0.9], [None])
    text, page = _parse(write_report(root))
    assert "calibration" in page.ids and "Confidence calibration" in page.h2
    section = text[text.index('<section id="calibration">'):]
    section = section[:section.index("</section>")]
    row = section[section.index("<tbody><tr>") + len("<tbody><tr>"):section.index("</tr></tbody>")]
    cells = [c.split(">", 1)[1] for c in row.split("</td>")[:-1]]
    # model, sequences, runs, frames, ECE, Brier, mean confidence, hit rate, mean ECE
    assert cells == ["m", "2", "3", "9", "0.400", "0.410", "0.900", "0.500", "0.500"]
    assert (root / FILES_DIR / "calibration.png").is_file()
    # runs without a confidence (colour-pf) get no calibration section
    colour_only = tmp_path / "colour"
    shutil.copytree(bench_dir / "runs" / "walker" / "colour-pf", colour_only)
    assert 'id="calibration"' not in write_report(colour_only).read_text()
    # a corrupt confidence is a one-line error naming the file
    bad = tmp_path / "bad"
    _scored_run(bad / "r", "A", [0.9, 1.5], [0.8, 0.8])
    with pytest.raises(InputError, match="confidence.values must lie in"):
        write_report(bad)


def test_runs_are_grouped_by_sequence_and_model(bench_dir):
    runs = [load_run(f, bench_dir) for f in find_runs(bench_dir)]
    assert len(runs) == 6
    groups = group_runs(r for r in runs if r.complete)
    keys = [(g.sequence, g.label, g.kind, len(g.runs)) for g in groups]
    assert keys == [("crowd", "phd", "multi", 2), ("walker", "colour-pf", "single", 2),
                    ("walker", "single-object", "single", 1)]


def test_two_configurations_of_one_model_are_told_apart(bench_dir, tmp_path):
    root = tmp_path / "exp"
    shutil.copytree(bench_dir / "runs" / "crowd" / "phd" / "0", root / "crowd" / "phd" / "0")
    shutil.copytree(bench_dir / "runs" / "crowd" / "phd" / "1",
                    root / "crowd" / "phd-scores" / "0")
    groups = group_runs(load_run(f, root) for f in find_runs(root))
    assert [g.label for g in groups] == ["phd", "phd-scores"]


@pytest.mark.parametrize("case", ["missing", "file", "empty", "corrupt", "not-an-object",
                                  "only-unfinished", "bad-series"])
def test_bad_input_is_one_line(case, bench_dir, tmp_path, capsys):
    target = tmp_path / "d"
    needle = {"missing": "no such folder", "file": "is not a folder",
              "empty": "no runs under", "corrupt": "metrics.json is corrupt",
              "not-an-object": "expected a JSON object",
              "only-unfinished": "no finished run",
              "bad-series": "expected a list of numbers"}[case]
    if case == "file":
        target.write_text("x")
    elif case != "missing":
        target.mkdir()
        (target / "notes.txt").write_text("nothing here")
    if case in ("corrupt", "not-an-object", "only-unfinished", "bad-series"):
        shutil.copytree(bench_dir / "runs" / "crowd" / "phd" / "0", target / "r")
        m = target / "r" / "metrics.json"
        if case == "corrupt":
            m.write_text('{"mota": 0.5,')
        elif case == "not-an-object":
            m.write_text("[1, 2]")
        elif case == "only-unfinished":
            (target / "r" / "run.json").write_text('{"complete": false}')
        else:
            data = json.loads(m.read_text())
            data["per_frame"]["ospa_50_1"] = "oops"
            m.write_text(json.dumps(data))
    with pytest.raises(InputError, match=needle):
        write_report(target)
    code, _, err = run_cli(capsys, "report", target)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pgm: error: ") and needle in lines[0]
    assert not (target / "report.html").exists()


def test_an_unreadable_model_is_noted_not_fatal(bench_dir, tmp_path):
    root = tmp_path / "r"
    shutil.copytree(bench_dir / "runs" / "walker" / "colour-pf" / "0", root)
    (root / "model.json").write_text('{"format": "something else"}')
    text = write_report(root).read_text()
    assert "could not be loaded" in text and 'id="otb-overall"' in text


def test_report_opens_in_headless_chromium(bench_dir, capsys):
    """The report renders in a real browser: every image decodes and the sections show."""
    from test_view import Browser, _need_browser  # same folder: on sys.path under pytest

    _need_browser()
    code, _, err = run_cli(capsys, "report", bench_dir)
    assert code == 0, err
    browser = Browser()
    try:
        browser.open(bench_dir / "report.html")
        browser.wait_for("document.readyState === 'complete'")
        n_img, decoded = browser.wait_for(
            "(() => { const im = [...document.images]; "
            "return im.length && im.every(i => i.complete) && "
            "[im.length, im.filter(i => i.naturalWidth > 0).length]; })()")
        assert n_img >= 4 and decoded == n_img
        assert browser.evaluate("!!document.getElementById('multi-target') && "
                                "!!document.getElementById('otb-overall')")
        assert len(browser.screenshot()) > 10_000
    finally:
        browser.close()
