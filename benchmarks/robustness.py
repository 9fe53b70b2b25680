"""The multi-target models under what a new detector or camera changes, against six peers.

    python benchmarks/robustness.py [--sequences A,B] [--kinds K,L] [--candidates C,D]
                                    [--jobs 2] [--no-peers] [--cache FILE] [--work DIR]

Each shared MOT sequence (PETS09-S2L1, TUD-Campus, TUD-Stadtmitte, MOT16-11 and the
PETS09-S2L1 video with its own detections) and the toolkit's synthetic crossing scene
(faster objects, a detector whose scores are probabilities) is perturbed by each kind of
:mod:`pgm.evaluation.perturb` (score maps: probability, logit, rank, affine, power; frame
rate ÷2 and ÷3 (a cell the mean over the two or three shares of the frames, each frame used
once); 20 % of the detections dropped; box jitter of 5 % of the size; 20 % more
false positives; the detector run at a lower threshold, as many more false detections
scored below all of its own; the detector run at a higher threshold, its lowest 40 % of
scores removed; boxes shifted and scaled as another detector's), seeded and
deterministic, and written as a sequence folder. On each, every candidate model of
:data:`CANDIDATES` runs as ``pgm track`` runs it (the frames decoded for the colour
models, the camera's motion estimated and compensated where it moves) and so do the six
trackers of the ``trackers`` package (SORT, ByteTrack, OC-SORT, BoT-SORT, C-BIoU, McByte;
default settings, their own venv: ``bash benchmarks/peers/setup_env.sh``), all scored by
:func:`pgm.evaluation.mot.evaluate_mot` (MOTA, IDF1, HOTA).

Tables: per kind, each sequence's MOTA / IDF1 / HOTA of every candidate and the best of
the peers in each metric. A candidate that reads scores only through their ranks (the
learned and quantile score maps, gated or not) gives the same tracks under every score map — exactly,
as ``tests/models/test_score_invariance.py`` checks on every shared sequence — so its
unperturbed row stands for the score-map kinds unless ``--run-invariant`` is given.
Then the default **chosen leave one sequence out**: for each
held-out sequence, the candidate with the best mean of (MOTA + IDF1 + HOTA) / 3 over the
other sequences and every kind (a fold leaves out a sequence with all its
perturbations), scored on the held-out sequence's kinds against the best peer; and per
kind, the worst margin over the held-out sequences. The same with a second criterion,
the issue's bar as a number: the worst margin to the best peer over the training
sequences and kinds (IDF1, HOTA, and MOTA with 0.01 of slack). Runs are cached as JSON lines in
``--cache`` (default ``benchmarks/results/robustness.jsonl``), so an interrupted run
resumes and a second call prints the tables at once.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, machine_note, print_table, single_thread  # noqa: E402

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11", "PETS09-S2L1-video",
             "synthetic")
#: the toolkit's synthetic crossing scene (``multi_target_scene``: six objects, births,
#: deaths, crossings, 640x480 at 30 frames/s, 150 frames), its detections drawn once
#: (2 px noise, a miss in ten, a clutter box a frame; scores are probabilities: targets in
#: [0.5, 1), clutter in [0, 0.6)) — faster objects than the shared pedestrians, and a
#: detector whose scores are probabilities
SYNTHETIC = "synthetic"
PEERS = ("sort", "bytetrack", "ocsort", "botsort", "cbiou", "mcbyte")
METRICS = ("mota", "idf1", "hota")

#: OC-SORT's rounds with ByteTrack's low-score round after them: the detections below the
#: threshold may extend a track (IoU at least 0.5, as BoT-SORT's second round), never
#: start one
OCSORT_LOW = ({"iou": 0.3, "min_score": 0.6, "direction": True},
              {"iou": 0.3, "min_score": 0.6, "against": "last"},
              {"iou": 0.5, "max_score": 0.6})
#: the least value above a gated quantile's 0 (q = 0: read as clutter; a detection kept
#: has q = u >= u* > 0, a mid-rank quantile): ``ocsort_colour.ABOVE_GATE``, which the test
#: holding the default equal to its candidate checks
GATED = 1e-9
#: OC-SORT's rounds, then the detections below their split and above the gate's 0 in
#: ByteTrack's low-score round (IoU at least 0.5): never those the gate reads as clutter
#: (the split at OC-SORT's 0.6, moved to the candidates' ``score_threshold``)
OCSORT_LOW_GATED = ({"iou": 0.3, "min_score": 0.6, "direction": True},
                    {"iou": 0.3, "min_score": 0.6, "against": "last"},
                    {"iou": 0.5, "min_score": GATED, "max_score": 0.6})
COLOUR = {"report": "estimate", "appearance": "colour", "appearance_weight": 1.0}
HITS = {"recover_hits": 1, "consecutive": False}
#: OC-SORT's own life cycle (three matches in a row after a miss), pinned: the
#: ``ocsort-colour`` model now has SORT's (the candidate chosen here)
OCSORT_LIFE = {"recover_hits": 3, "consecutive": True}

#: the default's life cycle and constants per second ("s30 birth0.3 tentative-prediction
#: recover3 fill0.5 births"), which the candidates on its score reading share
LIFE_S30 = {"reference_fps": 30.0, "birth_iou": 0.3, "explain_tentative": "prediction",
            "fill_gaps": 0.5, "recover_hits": 3, "consecutive": False, "fill_births": True}


def _presence_tracked(score_map: str, **fields) -> tuple[str, dict]:
    """An ``ocsort_colour`` candidate with the presence round on the tracked tracks (the
    low round keeps a track without updating it), the rates per second, a share cut of
    0.2 and the noise per detection: the default's family, its score map and ``fields``
    as given."""
    return ("ocsort_colour", {**LIFE_S30, "score_map": score_map, **fields,
                              "score_threshold": 0.2,
                              "rounds": OCSORT_LOW_GATED[:2] + ({**OCSORT_LOW_GATED[2],
                                                                "update": False,
                                                                "tracks": "tracked"},),
                              "noise_per": "detection"})


#: candidate models: label -> (model module name, Params fields)
CANDIDATES: dict[str, tuple[str, dict]] = {
    "ocsort-colour (detector scores)": ("ocsort_colour", {"score_map": "detector",
                                                          "score_threshold": None,
                                                          **OCSORT_LIFE}),
    "ocsort-colour learned 0.5": ("ocsort_colour", {"score_map": "learned",
                                                    "score_threshold": 0.5, **OCSORT_LIFE}),
    "ocsort-colour quantile 0.2": ("ocsort_colour", {"score_map": "quantile",
                                                     "score_threshold": 0.2, **OCSORT_LIFE}),
    "ocsort-colour+low quantile 0.4": ("ocsort_colour", {"score_map": "quantile",
                                                         "score_threshold": 0.4,
                                                         "rounds": OCSORT_LOW,
                                                         **OCSORT_LIFE}),
    "bytetrack-colour quantile": ("bytetrack", {"score_map": "quantile", **COLOUR}),
    # OC-SORT's association with SORT's life cycle: a track found again after a miss is
    # reported at once, and confirmation counts matches, not matches in a row
    "ocsort-colour learned 0.5 hits": ("ocsort_colour", {"score_map": "learned",
                                                         "score_threshold": 0.5,
                                                         **HITS}),
    "ocsort-colour quantile 0.2 hits": ("ocsort_colour", {"score_map": "quantile",
                                                          "score_threshold": 0.2, **HITS}),
    "ocsort-colour+low quantile 0.4 hits": ("ocsort_colour", {"score_map": "quantile",
                                                              "score_threshold": 0.4,
                                                              "rounds": OCSORT_LOW, **HITS}),
    # the same with its per-frame constants (confirmation, OC-SORT's momentum window, the
    # Kalman noise) given at a reference frame rate and converted to the video's
    # (models.sort.at_frame_rate): the choice sees the reference rate as the noise per second
    **{f"ocsort-colour quantile 0.2 hits s{r:g}": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": float(r), **HITS}) for r in (7.5, 15, 30)},
    "ocsort-colour scale quantile 0.2 hits s30": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2, "box_state": "xyxy",
                          "noise": "scale", "reference_fps": 30.0, **HITS}),
    # the default, no track born on a detection that overlaps a track's predicted box
    # (or a birth of the same frame) by more than the IoU: a detection another already
    # explains (a detector's duplicate, a part of a person) starts no second identity
    **{f"ocsort-colour quantile 0.2 hits s30 birth{b:g}": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": 30.0, "birth_iou": b, **HITS}) for b in (0.3, 0.5)},
    # and the birth rule on every match of a tentative track: its detection explained
    # by a confirmed track's prediction, or by a stronger detection a confirmed track has
    **{f"ocsort-colour quantile 0.2 hits s30 birth0.3 tentative-{e}": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": 30.0, "birth_iou": 0.3, "explain_tentative": e,
                          **HITS}) for e in ("prediction", "detection")},
    # the same with ByteTrack's low-score round after OC-SORT's: the lowest fifth of the
    # detections may extend a track (IoU at least 0.5), never start one
    "ocsort-colour+low quantile 0.2 hits s30 birth0.3": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2, "rounds": OCSORT_LOW,
                          "reference_fps": 30.0, "birth_iou": 0.3, **HITS}),
    # the default with the low-score round on the tracks matched in the previous frame
    # only (BoT-SORT's second round): a box below the threshold may keep a track going,
    # never make a tentative one
    "ocsort-colour+low-tracked quantile 0.2 hits s30 birth0.3 tentative-prediction": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "rounds": OCSORT_LOW[:2] + ({**OCSORT_LOW[2], "tracks": "tracked"},),
                          "reference_fps": 30.0, "birth_iou": 0.3,
                          "explain_tentative": "prediction", **HITS}),
    # the default, a track found again after a gap of at most 0.5 s reporting the gap's
    # frames too (boxes interpolated between the two it reported, in the camera's
    # world; frames another track explains left out), once it has been matched min_hits
    # frames in a row since
    "ocsort-colour quantile 0.2 hits s30 birth0.3 tentative-prediction fill0.5": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": 30.0, "birth_iou": 0.3,
                          "explain_tentative": "prediction", "fill_gaps": 0.5, **HITS}),
    # the same with a lost track found again reported after min_hits matches in a row
    # (the evidence a new track needs; the frames it waited are then part of its gap)
    **{f"ocsort-colour quantile 0.2 s30 birth0.3 tentative-prediction recover3 fill{g:g}": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": 30.0, "birth_iou": 0.3,
                          "explain_tentative": "prediction", "fill_gaps": g,
                          "recover_hits": 3, "consecutive": False})
       for g in (0.0, 0.25, 0.5)},
    # and a track confirmed reporting the frames it was tentative in (its confirmation
    # evidence asked, not frames lost), the counts of matches then kept as counts of
    # detections at every frame rate ("counts") or read as time (seconds)
    **{f"ocsort-colour quantile 0.2 s30 birth0.3 tentative-prediction recover3 fill0.5 "
       f"births{c}": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": 30.0, "birth_iou": 0.3,
                          "explain_tentative": "prediction", "fill_gaps": 0.5,
                          "recover_hits": 3, "consecutive": False, "fill_births": True,
                          "count_hits": "detections" if c else "seconds"})
       for c in ("", " counts")},
    # the same with the process noise a step per detection at any frame rate (its rates in
    # the video's units) instead of a random walk in time, and the counts of matches kept
    # as counts of detections too ("counts")
    **{f"ocsort-colour quantile 0.2 s30 birth0.3 tentative-prediction recover3 fill0.5 births "
       f"noise-per-detection{c}": (
        "ocsort_colour", {"score_map": "quantile", "score_threshold": 0.2,
                          "reference_fps": 30.0, "birth_iou": 0.3,
                          "explain_tentative": "prediction", "fill_gaps": 0.5,
                          "recover_hits": 3, "consecutive": False, "fill_births": True,
                          "noise_per": "detection",
                          "count_hits": "detections" if c else "seconds"})
       for c in ("", " counts")},
    # the default's thresholds on the learned probability that a detection is found
    # again in the next frame (PersistenceScoreModel), relative to the best-scored
    # detections', instead of on the scores' quantile (0.5, 0.7, 0.9), and the same with
    # the counts of matches kept as counts of detections ("counts")
    **{f"ocsort-colour learned {t:g} s30 birth0.3 tentative-prediction recover3 fill0.5 births "
       f"noise-per-detection{c}": (
        "ocsort_colour", {**LIFE_S30, "score_map": "learned", "score_threshold": t,
                          "noise_per": "detection",
                          "count_hits": "detections" if c else "seconds"})
       for t, c in ((0.5, ""), (0.5, " counts"), (0.7, ""), (0.9, ""))},
    # the default's quantile with the detections the learned model shows more likely
    # clutter than of a target read as 0 (PersistentQuantiles: "gated"), or the quantile
    # taken among the detections above them ("rebased"); both also with the counts of
    # detections ("counts")
    **{f"ocsort-colour quantile-{m} 0.2 s30 birth0.3 tentative-prediction recover3 "
       f"fill0.5 births noise-per-detection{c}": (
        "ocsort_colour", {**LIFE_S30, "score_map": f"quantile-{m}", "score_threshold": 0.2,
                          "noise_per": "detection",
                          "count_hits": "detections" if c else "seconds"})
       for m, c in (("gated", ""), ("gated", " counts"), ("rebased", ""),
                    ("rebased", " counts"))},
    # the gated quantile with no share of the detections dropped for its own sake: only
    # those the video shows more likely clutter (q = 0) are left out ("0+"), or the lowest
    # fifth above them may extend a track (IoU at least 0.5, ByteTrack's low-score round),
    # never start one ("low"): a detector run at a higher threshold has no clutter there
    "ocsort-colour quantile-gated 0+ s30 birth0.3 tentative-prediction recover3 fill0.5 "
    "births noise-per-detection": (
        "ocsort_colour", {**LIFE_S30, "score_map": "quantile-gated", "score_threshold": GATED,
                          "noise_per": "detection"}),
    "ocsort-colour+low quantile-gated 0.2 s30 birth0.3 tentative-prediction recover3 "
    "fill0.5 births noise-per-detection": (
        "ocsort_colour", {**LIFE_S30, "score_map": "quantile-gated", "score_threshold": 0.2,
                          "rounds": OCSORT_LOW_GATED, "noise_per": "detection"}),
    # the same with the low round on the tracks matched in the previous frame only
    # (BoT-SORT's second round: "tracked") or on the confirmed tracks ("confirmed")
    **{f"ocsort-colour+low-{w} quantile-gated 0.2 s30 birth0.3 tentative-prediction "
       f"recover3 fill0.5 births noise-per-detection": (
        "ocsort_colour", {**LIFE_S30, "score_map": "quantile-gated", "score_threshold": 0.2,
                          "rounds": OCSORT_LOW_GATED[:2] + ({**OCSORT_LOW_GATED[2],
                                                            "tracks": w},),
                          "noise_per": "detection"})
       for w in ("tracked", "confirmed")},
    # the same with the low round's matches keeping a track without updating it
    # ("presence": its box says the person is there, not where)
    **{f"ocsort-colour+presence{t} quantile-gated 0.2 s30 birth0.3 tentative-prediction "
       f"recover3 fill0.5 births noise-per-detection": (
        "ocsort_colour", {**LIFE_S30, "score_map": "quantile-gated", "score_threshold": 0.2,
                          "rounds": OCSORT_LOW_GATED[:2] + ({**OCSORT_LOW_GATED[2],
                                                            "update": False, **extra},),
                          "noise_per": "detection"})
       for t, extra in (("", {}), ("-tracked", {"tracks": "tracked"}),
                        *((f"-tracked-iou{g:g}", {"tracks": "tracked", "iou": g})
                          for g in (0.3, 0.7)))},
    # the default with the share cut relaxed where its own tracks show the detections
    # below it placed as well as the best-scored ones (at least `level` of their rate of
    # IoU >= 0.5 with a tracked person's predicted box): lifted to the threshold; and the
    # same over the rebased quantile ("placed-rebased": the share cut from the detections
    # above the clutter the video shows, so a detector run at a lower threshold, which
    # adds clutter below its usual output, has the same share of that output cut); and
    # that with the lifted boxes on a tracked person's predicted box lifted below the
    # clutter too ("placed-over": in a crowd the found-again rate reads them as clutter)
    **{f"ocsort-colour+presence-tracked {m}{v:g} 0.2 s30 birth0.3 tentative-prediction "
       f"recover3 fill0.5 births noise-per-detection": _presence_tracked(m, placed_level=v)
       for m, v in [("placed", v) for v in (0.6, 0.7, 0.8, 0.9)] + [("placed-rebased", 0.8),
                                                                    ("placed-over", 0.8)]},
    # the same with the clutter gate cutting only what the found-again rates show with a
    # stated confidence (a one-sided test: PersistentQuantiles(confidence=c)); not kept:
    # held out it lowers the mean (docs/results.md, "The clutter gate as a test")
    **{f"ocsort-colour+presence-tracked placed-over0.8 conf{c:g} 0.2 s30 birth0.3 "
       f"tentative-prediction recover3 fill0.5 births noise-per-detection": _presence_tracked(
           "placed-over", placed_level=0.8, gate_confidence=c) for c in (0.75, 0.84, 0.9, 0.95)},
    # the same with the process noise the step of a box's irregular displacement per
    # detection, in the video's pixels at any frame rate (a rate's variance unchanged too)
    "ocsort-colour quantile 0.2 s30 birth0.3 tentative-prediction recover3 fill0.5 births "
    "noise-per-displacement": (
        "ocsort_colour", {**LIFE_S30, "score_map": "quantile", "score_threshold": 0.2,
                          "noise_per": "displacement"}),
    # BoT-SORT's cascade (pooled rounds, IoU x score), its thresholds as quantiles
    "botsort quantile": ("botsort", {"score_map": "quantile"}),
    "botsort-colour quantile": ("botsort", {"score_map": "quantile", **COLOUR}),
    "botsort-colour learned": ("botsort", {"score_map": "learned", **COLOUR}),
    # the (VB-)PHD filters at their video defaults (models.phd.video_params), scores
    # through the learned model
    "phd learned": ("phd", {"score_model": "learned"}),
    "vb-phd learned": ("vb_phd", {"score_model": "learned"}),
}
#: the candidate the multi-target default (``pgm.models.ocsort_colour.Params()``) is
#: (``tests/test_benchmarks.py`` holds the two equal)
DEFAULT = ("ocsort-colour+presence-tracked placed-over0.8 0.2 s30 birth0.3 "
           "tentative-prediction recover3 fill0.5 births noise-per-detection")
#: what every ``ocsort_colour`` candidate starts from: OC-SORT's core reporting its
#: filtered boxes with the colour model — not the module's defaults, which are the
#: choice made here and move with it (a candidate is what its own fields say, whenever
#: it is run again)
OCSORT_COLOUR_BASE = {"report": "estimate", "appearance": "colour", "appearance_weight": 1.0}


def base_params(module_name: str):
    """The Params a candidate's fields are applied to: ``ocsort``'s with
    :data:`OCSORT_COLOUR_BASE` for an ``ocsort_colour`` candidate, the module's own
    defaults for the others (cores whose defaults are the packages' or the papers')."""
    import importlib

    if module_name == "ocsort_colour":
        from pgm.models import ocsort

        return replace(ocsort.Params(), **OCSORT_COLOUR_BASE)
    return importlib.import_module(f"pgm.models.{module_name}").Params()


#: the candidates run through pgm.app.runner.track_multi (their own track layer)
PHD_FAMILY = ("phd", "vb_phd")


def _frames_of(name: str, work: Path) -> list[Path] | None:
    """The image files of a shared sequence (a video's frames written once as JPEG under
    ``work``); None for an image folder (``perturb_sequence`` finds them)."""
    src = SHARED_DATA / name
    videos = sorted(src.glob("*.avi")) + sorted(src.glob("*.mp4"))
    if (src / "img1").is_dir() or not videos:
        return None
    import cv2

    out = work / "_frames" / name
    done = out / "done"
    if not done.is_file():
        out.mkdir(parents=True, exist_ok=True)
        cap = cv2.VideoCapture(str(videos[0]))
        k = 0
        while True:
            ok, image = cap.read()
            if not ok:
                break
            k += 1
            cv2.imwrite(str(out / f"{k:06d}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 95])
        cap.release()
        done.write_text(str(k))
    return sorted(out.glob("*.jpg"))


def source_folder(name: str, work: Path) -> Path:
    """A shared sequence's folder, or the synthetic scene's (written once under ``work``)."""
    if name != SYNTHETIC:
        return SHARED_DATA / name
    out = work / "_synthetic"
    if not (out / "seqinfo.ini").is_file():
        from pgm.synthetic.scenes import multi_target_scene

        scene = multi_target_scene(seed=0, n_frames=150, occluder=False)
        scene.write_mot(out, rng=0, sigma=2.0, clutter_rate=1.0)
    return out


def prepare_source(name: str, work: str) -> None:
    """Write what every kind of ``name`` reads (the synthetic scene's folder, a video's
    frames) once."""
    source_folder(name, Path(work))
    if name != SYNTHETIC:
        _frames_of(name, Path(work))


def phases(kind: str) -> int:
    """How many shares of the frames a kind has: a frame rate divided by ``k``, ``k`` (its
    cell is the mean over them, each frame used once: which share a video happens to keep
    is no part of what a kind of change is); any other kind, one."""
    from pgm.evaluation.perturb import frame_step

    return frame_step(kind)


def prepare(name: str, kind: str, work: Path, phase: int = 0) -> Path:
    """The perturbed folder of ``name`` under ``work`` (written once); a frame rate's
    share ``phase`` (the frames from ``1 + phase`` on: the perturbation's seed)."""
    from pgm.evaluation.perturb import perturb_sequence

    dst = work / name / (kind.replace("/", "-") + (f"-p{phase}" if phase else ""))
    if not (dst / "seqinfo.ini").is_file():
        frames = None if name == SYNTHETIC else _frames_of(name, work)
        perturb_sequence(source_folder(name, work), dst, kind, seed=phase, frames=frames)
    return dst


def mean_over_phases(runs: list[dict]) -> dict:
    """One cell's row from its shares' rows: each metric's mean, frames per second over
    them all (an error in any share is the cell's)."""
    errors = [r["error"] for r in runs if "error" in r]
    if errors:
        return {"error": errors[0]}
    out = {k: float(np.mean([r[k] for r in runs])) for k in METRICS}
    fps = [r.get("fps") for r in runs]
    out["fps"] = None if None in fps else float(np.mean(fps))
    if len(runs) > 1:
        out["phases"] = len(runs)
    return out


def run_candidate(label: str, folder: Path, motion: dict) -> dict:
    """One candidate on one perturbed folder: its metrics and inference frames/s."""
    import importlib

    from classic_trackers import run_graph

    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.models import sort
    from pgm.observation.detections import PublicDetections

    module_name, fields = CANDIDATES[label]
    module = importlib.import_module(f"pgm.models.{module_name}")
    if module_name in PHD_FAMILY:
        from mot_sequences import run

        from pgm.observation.detections import make_detector

        t0 = time.perf_counter()
        r = run(folder, module, make_detector("public", open_source(folder)), seed=0,
                overrides=fields)
        secs = time.perf_counter() - t0
        n = len(open_source(folder))
        return {**{k: float(r.metrics[k]) for k in METRICS},
                "fps": getattr(r, "fps", None) or n / secs}
    src = open_source(folder)
    det = PublicDetections(folder / "det" / "det.txt")
    gt = load_mot(folder / "gt" / "gt.txt", kind="gt")
    n = len(src)
    kw = dict(fields)
    if kw.get("score_map") == "detector":
        kw["score_map"] = sort.score_map_for(det.table.conf)
    p = replace(base_params(module_name), fps=float(src.fps), **kw)
    images = src if p.appearance else None
    table, secs, _ = run_graph(module.build_graph(p), det, n, motion=motion, images=images)
    m = evaluate_mot(gt.until(n), table, num_frames=n)
    return {**{k: float(m[k]) for k in METRICS}, "fps": n / secs if secs > 0 else None}


def run_peers(folder: Path, n: int) -> dict[str, dict]:
    from _peers import run_mot_peers

    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import load_mot

    gt = load_mot(folder / "gt" / "gt.txt", kind="gt")
    out = {}
    for name, r in run_mot_peers(folder, trackers=PEERS, workdir=folder / "_peers").items():
        if "error" in r:
            out[name] = {"error": r["error"]}
            continue
        m = evaluate_mot(gt.until(n), r["table"], num_frames=n)
        out[name] = {**{k: float(m[k]) for k in METRICS}, "fps": r.get("fps")}
    return out


def task(name: str, kind: str, labels: list[str], peers: bool, work: str) -> list[dict]:
    """Every candidate (and the peers) on one sequence under one kind: result rows (the
    camera's motion estimated once, as ``pgm track --camera-motion auto``)."""
    single_thread()
    from classic_trackers import camera_motions

    from pgm.io.video import open_source

    runs: dict[str, list[dict]] = {}
    seconds: dict[str, float] = {}
    for phase in range(phases(kind)):
        folder = prepare(name, kind, Path(work), phase)
        n = len(open_source(folder))
        motion = camera_motions(folder, n) if labels else {}
        for label in labels:
            t0 = time.perf_counter()
            try:
                r = run_candidate(label, folder, motion)
            except Exception as exc:  # reported in its row; the other runs go on
                r = {"error": f"{type(exc).__name__}: {exc}"}
            runs.setdefault(label, []).append(r)
            seconds[label] = seconds.get(label, 0.0) + time.perf_counter() - t0
        if peers:
            for peer, r in run_peers(folder, n).items():
                runs.setdefault(f"peer:{peer}", []).append(r)
    return [{"sequence": name, "kind": kind, "model": model, **mean_over_phases(rs),
             **({"seconds": seconds[model]} if model in seconds else {})}
            for model, rs in runs.items()]


def invariant(label: str) -> bool:
    """Whether a candidate reads scores only through their ranks (a learned or quantile
    map): its tracks under a score map are its tracks on the sequence as it is
    (``tests/models/test_score_invariance.py`` holds every core to that, exactly)."""
    from pgm.factors.scores import LEARNED_SCORE_MAPS

    module_name, fields = CANDIDATES[label]
    return fields.get("score_map", fields.get("score_model")) in LEARNED_SCORE_MAPS


def with_invariant_copies(results: dict, labels: list[str], seqs, kinds) -> dict:
    """``results`` plus, for each invariant candidate, its row of the unperturbed
    sequence under each score-map kind (marked ``"copied"``)."""
    from pgm.evaluation.perturb import SCORE_KINDS

    out = dict(results)
    for c in labels:
        if not invariant(c):
            continue
        for q in seqs:
            base = results.get((q, "none", c))
            for k in kinds:
                if k in SCORE_KINDS and (q, k, c) not in out and base is not None:
                    out[(q, k, c)] = {**base, "kind": k, "copied": True}
    return out


def load_cache(path: Path) -> dict[tuple[str, str, str], dict]:
    """The cached rows by (sequence, kind, model); rows with an error are left out (a
    candidate that failed is run again, a peer's error stays out of the best peer), and so
    are a frame rate's rows of one share of its frames (written before its cells were
    the mean over every share: run again)."""
    out = {}
    if path.is_file():
        for line in path.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                if "error" not in r and r.get("phases", 1) == phases(r["kind"]):
                    out[(r["sequence"], r["kind"], r["model"])] = r
    return out


def best_peer(results: dict, seq: str, kind: str) -> dict[str, float] | None:
    """Per metric, the best of the peers on ``seq`` under ``kind`` (None: none ran)."""
    rows = [r for (q, k, m), r in results.items() if q == seq and k == kind
            and m.startswith("peer:") and "error" not in r]
    if not rows:
        return None
    return {k: max(r[k] for r in rows) for k in METRICS}


def objective(results: dict, label: str, seqs, kinds, criterion: str = "mean") -> float:
    """``"mean"``: the mean of (MOTA + IDF1 + HOTA) / 3 over ``seqs`` × ``kinds``;
    ``"margin"``: the worst, over them, of the margin to the best peer (IDF1 and HOTA
    against theirs, MOTA against theirs less 0.01: the issue's bar as a number)."""
    cells = [(q, k) for q in seqs for k in kinds if (q, k, label) in results]
    if len(cells) < len(seqs) * len(kinds):
        return float("-inf")  # a candidate not run everywhere is not chosen
    if criterion == "mean":
        return float(np.mean([np.mean([results[(q, k, label)][m] for m in METRICS])
                              for q, k in cells]))
    worst = np.inf
    for q, k in cells:
        peer = best_peer(results, q, k)
        if peer is None:
            continue
        r = results[(q, k, label)]
        worst = min(worst, r["mota"] - peer["mota"] + 0.01, r["idf1"] - peer["idf1"],
                    r["hota"] - peer["hota"])
    return float(worst)


def loso(results: dict, labels: list[str], seqs: list[str], kinds: list[str],
         criterion: str = "mean") -> tuple[list[list], list[list]]:
    """The leave-one-sequence-out choice: per held-out sequence and kind, the chosen
    candidate's metrics and its margins over the best peer; and per kind the worst
    margins over the held-out sequences."""
    rows, worst = [], {k: [np.inf, np.inf, np.inf] for k in kinds}
    for held in seqs:
        train = [q for q in seqs if q != held]
        chosen = max(labels, key=lambda c: objective(results, c, train, kinds, criterion))
        for k in kinds:
            r = results.get((held, k, chosen))
            peer = best_peer(results, held, k)
            if r is None:
                continue
            margin = [r[m] - peer[m] for m in METRICS] if peer else [np.nan] * 3
            if peer:
                worst[k] = [min(a, b) for a, b in zip(worst[k], margin, strict=True)]
            rows.append([held, k, chosen] + [f"{r[m]:.3f}" for m in METRICS]
                        + [f"{x:+.3f}" for x in margin])
    worst_rows = [[k] + [f"{x:+.3f}" if np.isfinite(x) else "-" for x in worst[k]]
                  for k in kinds]
    return rows, worst_rows


def main(argv: list[str] | None = None) -> int:
    from pgm.evaluation.perturb import KINDS

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--candidates", default=None,
                    help=f"comma-separated labels (default: all of {list(CANDIDATES)})")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--run-invariant", dest="copy_invariant", action="store_false",
                    help="also run the candidates that read scores through their ranks under "
                         "the score maps (default: their unperturbed rows stand for them, "
                         "which tests/models/test_score_invariance.py holds exactly)")
    ap.add_argument("--cache", type=Path,
                    default=Path(__file__).resolve().parent / "results" / "robustness.jsonl")
    ap.add_argument("--work", type=Path, default=None,
                    help="where the perturbed folders go (default: a folder beside the cache)")
    args = ap.parse_args(argv)
    seqs = [q for q in args.sequences.split(",") if q == SYNTHETIC or (SHARED_DATA / q).is_dir()]
    if not seqs:
        sys.exit(f"none of {args.sequences} under {SHARED_DATA}")
    kinds = args.kinds.split(",")
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        sys.exit(f"unknown kinds {bad} (choose from {KINDS})")
    labels = list(CANDIDATES) if args.candidates is None else args.candidates.split(",")
    bad = [c for c in labels if c not in CANDIDATES]
    if bad:
        sys.exit(f"unknown candidates {bad} (choose from {list(CANDIDATES)})")
    work = args.work or args.cache.parent / "robustness-work"
    work.mkdir(parents=True, exist_ok=True)
    args.cache.parent.mkdir(parents=True, exist_ok=True)
    results = load_cache(args.cache)
    from pgm.evaluation.perturb import SCORE_KINDS

    todo = []
    for q in seqs:
        for k in kinds:
            missing = [c for c in labels if (q, k, c) not in results
                       and not (args.copy_invariant and k in SCORE_KINDS and invariant(c))]
            peers = not args.no_peers and not any(
                (q, k, f"peer:{p}") in results for p in PEERS)
            if missing or peers:
                todo.append((q, k, missing, peers))
    print(machine_note())
    print(f"{len(todo)} sequence x kind tasks to run ({len(results)} results cached)")
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        # the sources two tasks share (the synthetic scene, a video's frames) written once,
        # before any task reads them (in the workers: OpenCV is never loaded before a fork)
        for f in [pool.submit(prepare_source, q, str(work))
                  for q in dict.fromkeys(q for q, *_ in todo)]:
            f.result()
        futures = [pool.submit(task, q, k, c, p, str(work)) for q, k, c, p in todo]
        for f in futures:
            rows = f.result()
            with open(args.cache, "a") as fh:
                for r in rows:
                    fh.write(json.dumps(r) + "\n")
                    if "error" in r:
                        print(f"  {r['sequence']} {r['kind']} {r['model']}: {r['error']}")
                    else:
                        results[(r["sequence"], r["kind"], r["model"])] = r
            if rows:
                print(f"  done {rows[0]['sequence']} {rows[0]['kind']}", flush=True)

    if args.copy_invariant:
        results = with_invariant_copies(results, labels, seqs, kinds)
    for k in kinds:
        table = []
        for q in seqs:
            peer = best_peer(results, q, k)
            row = [q]
            for c in labels:
                r = results.get((q, k, c))
                row.append(" / ".join(f"{r[m]:.3f}" for m in METRICS) if r else "-")
            row.append(" / ".join(f"{peer[m]:.3f}" for m in METRICS) if peer else "-")
            table.append(row)
        print_table(["sequence"] + labels + ["best peer"], table,
                    title=f"kind {k}: MOTA / IDF1 / HOTA")
    print_table(["candidate", "mean of (MOTA+IDF1+HOTA)/3", "worst margin to the best peer"],
                [[c, f"{objective(results, c, seqs, kinds):.4f}",
                  f"{objective(results, c, seqs, kinds, 'margin'):+.3f}"] for c in labels],
                title="every sequence and kind (the choice on all of them)")
    for criterion in ("mean", "margin"):
        rows, worst = loso(results, labels, seqs, kinds, criterion)
        print_table(["held out", "kind", "chosen", "MOTA", "IDF1", "HOTA", "dMOTA", "dIDF1",
                     "dHOTA"], rows,
                    title=f"leave one sequence out, criterion {criterion} (d: minus the best "
                          f"peer)")
        print_table(["kind", "worst dMOTA", "worst dIDF1", "worst dHOTA"], worst,
                    title=f"criterion {criterion}: worst margin over the held-out sequences, "
                          f"per kind")
    return 0


if __name__ == "__main__":
    sys.exit(main())
