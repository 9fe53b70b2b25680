"""The teaching viewer: ``--record`` keeps a bounded record, ``pgm view`` writes a page
that a real browser (headless Chromium, driven over the DevTools protocol) steps through.

The browser tests skip, saying why, where Debian's ``chromium`` is not installed
(``.ci/run`` installs it) or ``websocket-client`` is missing; with
``PGM_REQUIRE_BROWSER=1`` (set by ``.ci/run`` when Chromium is there) they fail instead.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from pgm.app.record import RecordSettings, read_record, subsample
from pgm.app.runner import track, track_multi
from pgm.app.view import write_view
from pgm.core.errors import InputError
from pgm.synthetic import demo_scene, multi_target_scene

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def _need_browser():
    """Skip, saying why, without headless Chromium or the websocket client; fail instead
    where ``PGM_REQUIRE_BROWSER=1`` (``.ci/run`` sets it once Chromium is installed)."""
    why = None
    if CHROMIUM is None:
        why = ("Debian's chromium is not installed (apt-get install chromium; .ci/run "
               "installs it)")
    else:
        try:
            import websocket  # noqa: F401
        except ImportError:
            why = "websocket-client is not installed (pip install -e .[test])"
    if why is not None:
        if os.environ.get("PGM_REQUIRE_BROWSER") == "1":
            pytest.fail(f"the browser tests must run here: {why}")
        pytest.skip(why)


class Browser:
    """Headless Chromium driven over the Chrome DevTools Protocol (one page).

    Started with ``--remote-debugging-port=0``; the port is read from the profile's
    ``DevToolsActivePort`` file and the page's websocket from ``/json/list``.
    """

    def __init__(self, width: int = 1400, height: int = 1000, timeout: float = 60.0):
        import websocket

        self.profile = tempfile.mkdtemp(prefix="pgm-chromium-")
        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu",
             "--disable-dev-shm-usage", "--no-first-run", "--no-default-browser-check",
             "--disable-extensions", "--mute-audio", "--hide-scrollbars",
             f"--user-data-dir={self.profile}", "--remote-debugging-port=0",
             f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            port_file = Path(self.profile) / "DevToolsActivePort"
            deadline = time.monotonic() + timeout
            while not (port_file.is_file() and port_file.read_text().strip()):
                if self.proc.poll() is not None:
                    raise RuntimeError(f"chromium exited: {self.proc.stderr.read()[-2000:]!r}")
                if time.monotonic() > deadline:
                    raise RuntimeError("chromium did not open its DevTools port")
                time.sleep(0.05)
            port = int(port_file.read_text().split()[0])
            pages = []
            while not pages:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list") as r:
                    pages = [t for t in json.load(r) if t.get("type") == "page"]
                if time.monotonic() > deadline:
                    raise RuntimeError("chromium opened no page")
            self.ws = websocket.create_connection(pages[0]["webSocketDebuggerUrl"],
                                                  timeout=timeout, suppress_origin=True)
        except BaseException:
            self.close()
            raise
        self._id = 0
        self.events: list[dict] = []
        self.timeout = timeout

    def send(self, method: str, **params):
        """Send one command and return its result (events that arrive meanwhile are
        kept in :attr:`events`)."""
        self._id += 1
        self.ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    def evaluate(self, expression: str, await_promise: bool = False):
        """The value of a JavaScript expression in the page."""
        res = self.send("Runtime.evaluate", expression=expression, returnByValue=True,
                        awaitPromise=await_promise)
        if "exceptionDetails" in res:
            raise RuntimeError(f"{expression}: {res['exceptionDetails']}")
        return res["result"].get("value")

    def wait_for(self, expression: str, timeout: float | None = None):
        """Poll a JavaScript expression until it is truthy; return its value."""
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out waiting for {expression}")
            time.sleep(0.05)

    def open(self, path: Path) -> None:
        """Navigate to a local file (``file://``) and wait for its load event."""
        self.send("Page.enable")
        self.send("Runtime.enable")
        self.events.clear()
        self.send("Page.navigate", url=path.resolve().as_uri())
        deadline = time.monotonic() + self.timeout
        while not any(e.get("method") == "Page.loadEventFired" for e in self.events):
            if time.monotonic() > deadline:
                raise AssertionError(f"{path} did not load")
            self.events.append(json.loads(self.ws.recv()))

    def click(self, selector: str) -> None:
        """A real mouse click at the centre of the element ``selector``."""
        box = self.evaluate(f"(() => {{ const r = document.querySelector({json.dumps(selector)})"
                            f".getBoundingClientRect(); return [r.x + r.width / 2, "
                            f"r.y + r.height / 2]; }})()")
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=box[0], y=box[1],
                      button="left", clickCount=1)

    def key(self, key: str, code: int) -> None:
        """Press and release one key (e.g. ``"ArrowRight"``, 39) on the page."""
        for kind in ("keyDown", "keyUp"):
            self.send("Input.dispatchKeyEvent", type=kind, key=key, code=key,
                      windowsVirtualKeyCode=code, nativeVirtualKeyCode=code)

    def screenshot(self, selector: str | None = None) -> bytes:
        """PNG of the viewport, or of the element ``selector``."""
        params: dict = {"format": "png"}
        if selector is not None:
            r = self.evaluate(f"(() => {{ const r = document.querySelector({json.dumps(selector)})"
                              f".getBoundingClientRect(); return [r.x, r.y, r.width, "
                              f"r.height]; }})()")
            params["clip"] = {"x": r[0], "y": r[1], "width": r[2], "height": r[3], "scale": 1}
        return base64.b64decode(self.send("Page.captureScreenshot", **params)["data"])

    def close(self) -> None:
        """Close the connection, end the browser, remove its profile."""
        ws = getattr(self, "ws", None)
        if ws is not None:
            try:
                ws.close()
            except Exception:  # noqa: BLE001 - closing anyway
                pass
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stderr is not None:
            self.proc.stderr.close()
        shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture(scope="module")
def part_run(tmp_path_factory):
    """A recorded part-graph run (particle BP messages) on a few synthetic frames."""
    from pgm.models import part_graph

    root = tmp_path_factory.mktemp("view")
    seq = demo_scene(seed=0, n_frames=6).write_otb(root / "seq")
    graph = part_graph.build_graph(part_graph.Params(init_box=(35, 140, 30, 80), n_parts=2,
                                                     num_particles=40))
    out = root / "run"
    track(seq, graph, rng=np.random.default_rng(0), out_dir=out, progress=False,
          show_particles=True, record=RecordSettings(particles=25, frames=5))
    return out


@pytest.fixture(scope="module")
def vb_run(tmp_path_factory):
    """A recorded VB-PHD run (intensity, extracted targets, VB fixed point)."""
    from pgm.io.video import open_source
    from pgm.models import phd, vb_phd
    from pgm.observation.detections import make_detector

    root = tmp_path_factory.mktemp("vbview")
    seq = multi_target_scene(seed=0, n_frames=5, n_objects=3).write_mot(root / "seq")
    src = open_source(seq)
    graph = vb_phd.build_graph(phd.video_params(vb_phd.Params, *src.size, src.fps))
    out = root / "run"
    track_multi(src, graph, make_detector("public", src), rng=np.random.default_rng(0),
                out_dir=out, progress=False, record=RecordSettings(particles=30),
                gt=seq / "gt" / "gt.txt")
    return out


# -- the record ----------------------------------------------------------------------
def test_subsample_keeps_the_heaviest_and_spreads_the_rest():
    w = np.linspace(0.0, 1.0, 100) ** 4
    idx = subsample(w, 10)
    assert len(idx) == 10 and np.all(np.diff(idx) > 0)
    assert set(range(95, 100)) <= set(idx.tolist())  # the five heaviest
    assert idx.min() < 20  # and light ones from the whole cloud
    assert np.array_equal(subsample(w[:7], 10), np.arange(7))


def test_record_is_bounded_and_holds_what_the_viewer_needs(part_run):
    meta, frames = read_record(part_run / "record")
    run = json.loads((part_run / "run.json").read_text())
    assert run["record"]["id"] == meta["id"] and run["record"]["frames_recorded"] == 5
    assert len(frames) == 5  # capped at --record-frames: the first five of six
    assert [f["frame"] for f in frames] == [1, 2, 3, 4, 5]
    assert meta["closed"] is True and meta["image_size"] == [320, 240]
    for f in frames:
        assert (part_run / "record" / f["image"]).is_file()
        for v in ("top", "bottom"):
            d = f["variables"][v]
            assert len(d["x"]) == len(d["w"]) <= 25 and d["n"] >= 40
            assert 0 < d["shown_mass"] <= 1 + 1e-6
        assert {(m["factor"], m["src"], m["dst"]) for m in f["messages"]} == {
            ("coupling:top-bottom", "top", "bottom"), ("coupling:top-bottom", "bottom", "top")}
        assert all(len(m["x"]) == len(m["w"]) <= 25 for m in f["messages"])
        assert f["targets"]["ids"] == [1]


def test_recording_changes_no_result(tmp_path):
    from pgm.models import colour_pf

    seq = demo_scene(seed=1, n_frames=4).write_otb(tmp_path / "seq")
    g = colour_pf.build_graph(colour_pf.Params(init_box=(35, 140, 30, 80)))
    a = track(seq, g, rng=np.random.default_rng(3), out_dir=tmp_path / "a", progress=False,
              write_video=False, num_particles=30)
    b = track(seq, g, rng=np.random.default_rng(3), out_dir=tmp_path / "b", progress=False,
              write_video=False, num_particles=30, record={"particles": 5, "every": 2})
    assert np.array_equal(a.boxes, b.boxes)
    assert not (tmp_path / "a" / "record").exists()
    assert "record" not in json.loads((tmp_path / "a" / "run.json").read_text())
    _, frames = read_record(tmp_path / "b" / "record")
    assert [f["frame"] for f in frames] == [1, 3]  # every 2nd frame
    with pytest.raises(InputError, match="output folder"):
        track(seq, g, rng=np.random.default_rng(3), progress=False, record=True)


def test_interrupted_run_keeps_its_record_and_can_be_viewed(tmp_path):
    from pgm.models import colour_pf

    seq = demo_scene(seed=0, n_frames=5)
    g = colour_pf.build_graph(colour_pf.Params(init_box=(35, 140, 30, 80)))

    def frames():
        for k in range(1, 6):
            if k == 4:
                raise KeyboardInterrupt
            yield k, seq.frames[k - 1]

    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        track(frames(), g, rng=np.random.default_rng(0), out_dir=out, progress=False,
              num_particles=20, record=True)
    run = json.loads((out / "run.json").read_text())
    assert run["complete"] is False and run["record"]["frames_recorded"] == 3
    meta, recorded = read_record(out / "record")
    assert meta["closed"] is True and len(recorded) == 3
    assert not (out / "model.json").exists()  # the page draws the record's graph.json
    assert 'data-node="likelihood:object"' in write_view(out).read_text()


def test_vb_phd_record_holds_the_intensity_and_the_fixed_point(vb_run):
    meta, frames = read_record(vb_run / "record")
    last = frames[-1]
    s = last["sets"]["targets"]
    assert 0 < len(s["x"]) <= 30 and s["n"] >= len(s["x"]) and s["mass"] > 0
    vb = last["vb"]["conjugate:noise-targets"]
    assert vb["iterations"] >= 1 and len(vb["elbo"]) >= 1 and len(vb["sigma"]) == 2
    assert "measurements" in last and meta["variables"]["targets"]["image"] is True


def test_plate_record_holds_the_replicas(tmp_path):
    from pgm.io.video import open_source
    from pgm.models import multi_pf
    from pgm.observation.detections import make_detector

    seq = multi_target_scene(seed=0, n_frames=4, n_objects=2).write_mot(tmp_path / "seq")
    src = open_source(seq)
    out = tmp_path / "run"
    track_multi(src, multi_pf.build_graph(multi_pf.Params(num_particles=30)),
                make_detector("public", src), rng=np.random.default_rng(0), out_dir=out,
                progress=False, write_video=False, record=RecordSettings(particles=40))
    _, frames = read_record(out / "record")
    reps = frames[-1]["replicas"]["person"]
    assert len(reps) >= 1
    assert all(len(r["x"]) <= max(10, -(-40 // len(reps))) for r in reps)
    assert "plate" in frames[-1] and write_view(out).is_file()


# -- the page (no browser) -----------------------------------------------------------
def test_view_page_is_self_contained(part_run):
    page = write_view(part_run)
    assert page == part_run / "view.html"
    text = page.read_text()
    assert 'id="frame-counter"' in text and 'id="graph-svg"' in text
    assert text.count("data:image/jpeg;base64,") == 5
    assert "data:video/mp4;base64," in text  # the annotated video is embedded
    assert "<script src" not in text and "<link" not in text and "http://" not in text.replace(
        "http://www.w3.org/2000/svg", "")


def test_view_refuses_a_stale_record(tmp_path, part_run):
    run = tmp_path / "run"
    shutil.copytree(part_run, run)
    status = json.loads((run / "run.json").read_text())
    del status["record"]  # a later run without --record in the same folder
    (run / "run.json").write_text(json.dumps(status))
    with pytest.raises(InputError, match="earlier run"):
        write_view(run)
    with pytest.raises(InputError, match="no record"):
        write_view(tmp_path)


def test_pgm_view_command(part_run, tmp_path, capsys):
    from pgm.app.cli import main

    out = tmp_path / "page.html"
    assert main(["view", str(part_run), "--out", str(out), "--max-video-mb", "0"]) == 0
    assert out.is_file() and "data:video/mp4" not in out.read_text()
    assert "wrote" in capsys.readouterr().out


def test_track_record_options(tmp_path, capsys):
    from pgm.app.cli import main

    seq = demo_scene(seed=0, n_frames=3).write_otb(tmp_path / "seq")
    out = tmp_path / "run"
    code = main(["track", str(seq), "--model", "colour-pf", "--out", str(out), "--quiet",
                 "--no-video", "--particles", "20", "--record-particles", "7",
                 "--record-frames", "2"])
    assert code == 0, capsys.readouterr().err
    meta, frames = read_record(out / "record")
    assert len(frames) == 2 and meta["settings"]["particles"] == 7
    assert all(len(f["variables"]["object"]["x"]) <= 7 for f in frames)


# -- in a real browser ---------------------------------------------------------------
def test_viewer_steps_through_frames_in_chromium(part_run):
    _need_browser()
    page = write_view(part_run)
    browser = Browser()
    try:
        browser.open(page)
        browser.wait_for("document.body.dataset.shown === '0'")
        assert browser.evaluate("document.getElementById('frame-counter').textContent") == "1"
        first = browser.screenshot("#stage")
        browser.click("#next")  # frame 2
        browser.wait_for("document.body.dataset.shown === '1'")
        browser.key("ArrowRight", 39)  # frame 3
        browser.wait_for("document.body.dataset.shown === '2'")
        assert browser.evaluate("document.getElementById('frame-counter').textContent") == "3"
        third = browser.screenshot("#stage")
        assert first != third
        # the active factor (the coupling whose messages are shown) is highlighted
        active = browser.evaluate("[...document.querySelectorAll('#graph-svg g.active')]"
                                  ".map(g => g.dataset.node).sort()")
        assert "coupling:top-bottom" in active
        browser.key("ArrowLeft", 37)
        browser.wait_for("document.body.dataset.shown === '1'")
        assert browser.evaluate("document.getElementById('frame-counter').textContent") == "2"
        browser.evaluate("const s = document.getElementById('slider'); s.value = s.max; "
                         "s.dispatchEvent(new Event('input'))")
        assert browser.evaluate("document.getElementById('frame-counter').textContent") == "5"
        # the embedded annotated video (H.264) is decoded by the browser
        size = browser.wait_for("(() => { const v = document.getElementById('video'); "
                                "return v.readyState >= 1 && [v.videoWidth, v.videoHeight]; })()")
        assert size == [320, 240]
    finally:
        browser.close()


def test_vb_phd_viewer_in_chromium(vb_run):
    _need_browser()
    page = write_view(vb_run)
    browser = Browser()
    try:
        browser.open(page)
        browser.wait_for("document.body.dataset.shown === '0'")
        browser.click("#next")
        browser.wait_for("document.body.dataset.shown === '1'")
        browser.click("#graph-svg g[data-node='conjugate:noise-targets']")
        info = browser.evaluate("document.getElementById('info').textContent")
        assert "ELBO" in info and "iterations" in info
        assert browser.evaluate("document.querySelectorAll('#chart-elbo circle').length") >= 1
        assert browser.evaluate("[...document.querySelectorAll('#graph-svg g.active')]"
                                ".map(g => g.dataset.node)").count("conjugate:noise-targets") == 1
    finally:
        browser.close()
