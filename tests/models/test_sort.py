"""SORT and ByteTrack as model configs: exact Kalman replicas, association as a factor."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgm import FactorGraph, Variable
from pgm.core.boxes import decode_boxes, encode_boxes
from pgm.core.expfam import Gaussian
from pgm.core.frame import FrameContext
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.factors.association import (
    AssignedDetectionLikelihood,
    DetectionAssociation,
    map_scores,
)
from pgm.factors.multitarget import InverseGammaPrior, NoiseForgetting, VBNoise
from pgm.inference import Engine
from pgm.inference.association import TrackState
from pgm.inference.kalman import kalman_filter
from pgm.models import bytetrack, sort
from pgm.observation.detections import Detections


def _frame(t, boxes_xywh, scores=None):
    b = np.asarray(boxes_xywh, dtype=float).reshape(-1, 4)
    s = np.full(len(b), 0.9) if scores is None else np.asarray(scores, dtype=float)
    return FrameContext(t, detections=Detections(b, s))


def _walk(n=30, seed=0, sigma=1.5, size_sigma=None):
    """One person walking: noisy top-left boxes ``(n, 4)`` (``sigma`` px on the position,
    ``size_sigma`` on the size, default the same)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None]
    truth = np.array([100.0, 80.0, 40.0, 100.0]) + t * np.array([3.0, 1.0, 0.2, 0.5])
    s = sigma if size_sigma is None else size_sigma
    return truth + np.array([sigma, sigma, s, s]) * rng.standard_normal(truth.shape)


@pytest.mark.parametrize("box_state", ["xyxy", "xysr"])
def test_one_target_is_the_kalman_filter(box_state):
    """A replica's belief is the Kalman filter's on its detections (coded as its state),
    born with its first detection as the prior mean and no update in that frame."""
    p = sort.Params(box_state=box_state)
    g = sort.build_graph(p)
    eng = Engine(g, 0)
    boxes = _walk()
    cx = boxes.copy()
    cx[:, :2] += cx[:, 2:] / 2
    z = encode_boxes(cx, box_state)
    f, q, lik = g.factors["transition:box"], g.factors["prior:box"], g.factors["detection"]
    m0 = np.zeros(q.mean_.size)
    m0[:4] = z[0]
    ys = z.copy()
    ys[0] = np.nan  # the birth frame: the prior, no update
    kf = kalman_filter(m0, q.cov, f.F, f.Q, lik.H, lik.R, ys)
    for t, b in enumerate(boxes):
        eng.step(_frame(t + 1, b))
        belief = eng.beliefs["box"]
        assert belief.K == 1
        np.testing.assert_allclose(belief.mean()[0], kf.filtered_means[t], rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(belief.cov()[0], kf.filtered_covs[t], rtol=1e-10, atol=1e-9)


def test_vb_sort_one_replica_is_the_vb_adaptive_kalman_filter():
    """``vb_noise``: a replica's state and noise beliefs are those of the single-graph VB
    adaptive Kalman filter (Feng et al.'s (2015) per-target noise) fed its detections."""
    p = sort.Params(vb_noise=True, vb_rho=0.9)
    g = sort.build_graph(p)
    eng = Engine(g, 0)
    boxes = _walk(sigma=3.0, size_sigma=1.0, seed=3)
    cx = boxes.copy()
    cx[:, :2] += cx[:, 2:] / 2
    z = encode_boxes(cx, "xyxy")
    tr, prior, lik = g.factors["transition:box"], g.factors["prior:box"], g.factors["detection"]
    vb = g.factors["vb"]
    m0 = np.zeros(8)
    m0[:4] = z[0]
    single = FactorGraph(
        [Variable("x", 8), Variable("noise", 4, role="noise")],
        [GaussianPrior("x", mean=m0, cov=prior.cov), LinearGaussianTransition("x", F=tr.F, Q=tr.Q),
         LinearGaussianLikelihood("x", H=lik.H, R=lik.R),
         InverseGammaPrior("noise", sigma=np.sqrt(np.diag(lik.R)), alpha=p.vb_alpha0),
         NoiseForgetting("noise", rho=0.9, alpha_min=2.0),
         VBNoise("noise", "x", tol=vb.tol, max_iter=vb.max_iter)])
    oracle = Engine(single, 0, belief_types={"x": Gaussian})
    for t, b in enumerate(boxes):
        rec = eng.step(_frame(t + 1, b))
        assert rec.plate.births == (t == 0)  # one track throughout
        oracle.step(FrameContext(t + 1, measurements=None if t == 0 else z[t]))
        np.testing.assert_allclose(eng.beliefs["box"].mean()[0], oracle.beliefs["x"].mean(),
                                   rtol=1e-9, atol=1e-8)
        q, q0 = eng.beliefs["noise"].row(0), oracle.beliefs["noise"]
        np.testing.assert_allclose(q.beta / q.alpha, q0.beta / q0.alpha, rtol=1e-9)
    # the learned noise is far above the assumed R = 0.1 (the corners jitter by 3 px)
    assert np.all(q.beta / q.alpha > 10 * 0.1)


def test_sort_life_cycle_confirms_coasts_and_ends():
    """SORT's life cycle: confirmed at the third match (identity then), reported only in
    frames with a match (the detection's box), kept ``ceil(fps)`` frames without one and
    then removed; a tentative track ends at its first miss."""
    eng = Engine(sort.build_graph(sort.Params(fps=5.0)), 0)  # kept 5 frames unmatched
    box = np.array([100.0, 100.0, 40.0, 100.0])
    other = np.array([400.0, 100.0, 40.0, 100.0])
    reported = []
    for t in range(1, 4):
        rec = eng.step(_frame(t, [box + [t, 0, 0, 0], other] if t == 1 else box + [t, 0, 0, 0]))
        info = rec.plate
        reported.append(int(info["reported"].sum()))
    assert reported == [0, 0, 1]  # confirmed at the third detection
    assert eng.num_targets == 1  # the other, tentative, ended at its first miss
    track_id = int(info["ids"][0])
    np.testing.assert_allclose(info["boxes"][0], [123.0, 150.0, 40.0, 100.0])  # centre box
    for t in range(4, 10):  # six frames without a detection: kept five, then removed
        rec = eng.step(_frame(t, np.zeros((0, 4))))
        assert not rec.plate.reported.any()
        assert eng.num_targets == (1 if t < 9 else 0)
    # found again before the end: reported at once under its identity
    eng = Engine(sort.build_graph(sort.Params(fps=5.0)), 0)
    for t in range(1, 4):
        eng.step(_frame(t, box))
    first = int(eng.tracks[0].track_id)
    for t in range(4, 7):
        eng.step(_frame(t, np.zeros((0, 4))))
    rec = eng.step(_frame(7, box))
    assert rec.plate.reported.tolist() == [True]
    assert int(rec.plate.ids[0]) == first == track_id


def test_bytetrack_second_round_and_streak():
    """ByteTrack: the high-score detections are assigned first, the low-score ones only to
    the replicas left over; confirmation needs two matches in a row; a low-score
    detection never starts a track."""
    box = np.array([100.0, 100.0, 40.0, 100.0])
    near_low = box + [1, 0, 0, 0]  # IoU ~0.95 with the track's prediction
    far_high = box + [15, 0, 0, 0]  # IoU ~0.45
    out = {}
    for name, module in (("sort", sort), ("bytetrack", bytetrack)):
        eng = Engine(module.build_graph(module.Params()), 0)
        for t in range(1, 4):
            eng.step(_frame(t, box))
        rec = eng.step(_frame(4, [near_low, far_high], scores=[0.3, 0.9]))
        info = rec.plate
        k = int(np.flatnonzero(info["ids"] == eng.tracks[0].track_id)[0])
        out[name] = info["boxes"][k, 0] - box[2] / 2
    assert out["sort"] == pytest.approx(near_low[0])  # one round: the best IoU
    assert out["bytetrack"] == pytest.approx(far_high[0])  # high scores first
    eng = Engine(bytetrack.build_graph(bytetrack.Params()), 0)
    eng.step(_frame(1, box, scores=[0.5]))  # below activation (0.7): no track
    assert eng.num_targets == 0
    rec = eng.step(_frame(2, box, scores=[0.8]))
    assert eng.num_targets == 1 and not rec.plate.reported.any()
    rec = eng.step(_frame(3, box, scores=[0.8]))
    assert rec.plate.reported.tolist() == [True]  # two in a row


def test_association_rounds_and_scores():
    f = DetectionAssociation("box", rounds=bytetrack.rounds(0.6, 0.1), score_map="logistic")
    assert f.params()["rounds"][0] == {"iou": 0.1, "min_score": 0.6, "max_score": None}
    again = DetectionAssociation("box", **json.loads(json.dumps(f.params())))
    assert again.rounds == f.rounds
    np.testing.assert_allclose(map_scores(np.array([-800.0, 0.0, 800.0]), "logistic"),
                               [0.0, 0.5, 1.0])
    assert sort.score_map_for(np.array([0.1, 0.9])) == "none"
    assert sort.score_map_for(np.array([-1.0, 0.5])) == "logistic"
    assert sort.score_map_for(np.array([3.0, 120.0])) == "logistic"
    with pytest.raises(ValueError, match="iou gate"):
        DetectionAssociation("box", rounds=[{"iou": 1.5}])
    with pytest.raises(ValueError, match="round is a dict"):
        DetectionAssociation("box", rounds=[{"gate": 0.3}])
    with pytest.raises(ValueError, match="score_map"):
        DetectionAssociation("box", score_map="softmax")


def test_box_codings_round_trip():
    rng = np.random.default_rng(0)
    b = np.column_stack([rng.uniform(0, 500, (50, 2)), rng.uniform(5, 200, (50, 2))])
    for coding in ("cxcywh", "xyxy", "xysr"):
        np.testing.assert_allclose(decode_boxes(encode_boxes(b, coding), coding), b,
                                   rtol=1e-12)
    assert np.isnan(decode_boxes(np.array([10.0, 10.0, -4.0, 1.0]), "xysr")[2])


def test_sort_graph_saves_loads_and_draws(tmp_path):
    from pgm.plotting.graph_drawing import to_dot

    g = sort.build_graph(sort.Params(vb_noise=True))
    path = tmp_path / "sort.json"
    g.save(path)
    loaded = FactorGraph.load(path)
    assert loaded.factors["association"].rounds == g.factors["association"].rounds
    assert loaded.meta["engine"]["beliefs"] == {"box": "gaussian"}
    dot = to_dot(loaded)
    assert "association" in dot
    boxes = _walk(12)
    runs = []
    for graph in (g, loaded):
        eng = Engine(graph, 0)
        for t, b in enumerate(boxes):
            eng.step(_frame(t + 1, b))
        runs.append(eng.beliefs["box"].mean().copy())
    np.testing.assert_array_equal(runs[0], runs[1])


def test_bad_settings_are_value_errors():
    with pytest.raises(ValueError, match="box_state"):
        sort.build_graph(sort.Params(box_state="xywh"))
    with pytest.raises(ValueError, match="min_hits"):
        sort.build_graph(sort.Params(min_hits=0))
    with pytest.raises(ValueError, match="process_noise needs 8"):
        sort.build_graph(sort.Params(process_noise=(0.1,) * 7))
    with pytest.raises(ValueError, match="measurement_noise"):
        sort.build_graph(sort.Params(measurement_noise=(0.1, 0.1, np.nan, 0.1)))
    with pytest.raises(ValueError, match="positive definite"):
        AssignedDetectionLikelihood("box", H=np.eye(4, 8), R=-np.eye(4))
    # association links a plate's replicas: a graph without a plate is refused
    g = FactorGraph([Variable("box", 8, labels=("x1", "y1", "x2", "y2", "a", "b", "c", "d"))],
                    [GaussianPrior("box", mean=np.zeros(8), cov=1.0),
                     DetectionAssociation("box")])
    with pytest.raises(ValueError, match="declares no plate"):
        Engine(g, 0)


@pytest.mark.parametrize("box_state", ["xyxy", "xysr"])
def test_camera_motion_moves_the_kalman_states(box_state):
    """With the camera's image motion in the frame, a predict first moves each replica's
    mean and covariance through it (``T m + c``, ``T P Tᵀ``): a person standing still
    while the camera pans and zooms keeps zero velocity, where the filter without it
    learns the pan as motion."""
    A = np.array([[1.02, 0.0, -8.0], [0.0, 1.02, 3.0]])  # zoom 2 % and pan, per frame
    box = np.array([300.0, 200.0, 40.0, 100.0])  # centre box in frame 1
    vel = {}
    for cmc in (True, False):
        eng = Engine(sort.build_graph(sort.Params(box_state=box_state)), 0)
        b = box.copy()
        for t in range(1, 12):
            ctx = _frame(t, np.r_[b[:2] - b[2:] / 2, b[2:]])
            if cmc and t > 1:
                ctx = FrameContext(t, detections=ctx.detections, camera_motion=A)
            eng.step(ctx)
            b = np.r_[A[:, :2] @ b[:2] + A[:, 2], b[2:] * 1.02]
        assert eng.num_targets == 1
        vel[cmc] = eng.beliefs["box"].mean()[0, 4:]
    assert np.abs(vel[True]).max() < 1e-6
    assert np.abs(vel[False]).max() > 1.0


@pytest.mark.parametrize("camera_warp", ["box", "centre", "none"])
def test_camera_motion_moves_the_last_observations(camera_warp):
    """OC-SORT's recovery round and momentum read each replica's last detection and its
    observation history: with the camera's motion in the frame they move into the frame's
    coordinates as the Kalman state does (the whole box, its centre only, or not at all
    with ``camera_warp="none"``), so a box from before a pan is compared with this frame's
    detections in one frame's coordinates."""
    from pgm.models import ocsort

    A = np.array([[1.1, 0.0, -30.0], [0.0, 1.1, 12.0]])  # zoom 10 % and pan
    box = np.array([300.0, 200.0, 40.0, 100.0])  # centre box
    eng = Engine(ocsort.build_graph(ocsort.Params(camera_warp=camera_warp)), 0)
    for t in range(1, 5):
        eng.step(_frame(t, np.r_[box[:2] - box[2:] / 2, box[2:]]))
    eng.step(FrameContext(5, detections=Detections(np.zeros((0, 4)), np.zeros(0)),
                          camera_motion=A))  # missed while the camera moves
    moved = {"box": np.r_[A[:, :2] @ box[:2] + A[:, 2], box[2:] * 1.1],
             "centre": np.r_[A[:, :2] @ box[:2] + A[:, 2], box[2:]], "none": box}[camera_warp]
    (t,) = eng.replicas.tracks
    np.testing.assert_allclose(t.state, moved)
    history = eng.replicas.state[0].get("box", TrackState).observations
    np.testing.assert_allclose(history.boxes[max(history.boxes)], moved)


@pytest.mark.slow
def test_vb_sort_holds_where_the_measurement_noise_is_mis_specified(tmp_path):
    """Feng et al.'s (2015) claim on the SORT core: with the detection noise set ten times too large
    (or ten times too small on noisier detections), VB-SORT, which learns each target's
    noise, tracks at least as well as SORT with the same wrong setting, in MOTA and IDF1
    (synthetic scene, means of three detection draws): better where the noise is too
    large; where it is too small the VB fixed point barely moves from its prior (the
    filter follows every detection, so the residuals it learns from are small)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from classic_trackers import run_graph

    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import load_mot
    from pgm.models import vb_sort
    from pgm.observation.detections import PublicDetections
    from pgm.synthetic.scenes import multi_target_scene

    seq = multi_target_scene(seed=0, n_frames=100, occluder=False)
    for sigma, factor in ((2.0, 10.0), (5.0, 0.1)):
        scores = {"sort": [], "vb-sort": []}
        for seed in range(3):
            d = seq.write_mot(tmp_path / f"s{sigma}-{seed}", rng=seed, sigma=sigma)
            det = PublicDetections(d / "det" / "det.txt")
            gt = load_mot(d / "gt" / "gt.txt", kind="gt").until(100)
            for name, module in (("sort", sort), ("vb-sort", vb_sort)):
                p = module.Params(fps=30.0, noise="scale", meas_std=0.05 * factor)
                table, _, _ = run_graph(module.build_graph(p), det, 100)
                m = evaluate_mot(gt, table, num_frames=100)
                scores[name].append((m["mota"], m["idf1"]))
        sort_m, vb_m = np.mean(scores["sort"], 0), np.mean(scores["vb-sort"], 0)
        assert vb_m[0] >= sort_m[0] and vb_m[1] >= sort_m[1], (sigma, factor, sort_m, vb_m)
        if factor > 1:
            assert vb_m[0] > sort_m[0] and vb_m[1] > sort_m[1], (sigma, factor, sort_m, vb_m)


def test_ocsort_recovery_reupdate_and_life_cycle():
    """OC-SORT's pieces: a person lost for a few frames while walking is matched again by
    the recovery round against its last detection (its prediction has drifted off), its
    velocity re-estimated by the re-update along the gap, and it is reported again only
    after three matches in a row; a tentative track survives a miss."""
    from pgm.models import ocsort

    eng = Engine(ocsort.build_graph(ocsort.Params(fps=30.0)), 0)
    box = np.array([100.0, 100.0, 40.0, 100.0])
    step = np.array([6.0, 0.0, 0.0, 0.0])
    for t in range(1, 8):  # warm-up frames then steady: confirmed and reported
        rec = eng.step(_frame(t, box + t * step))
    assert rec.plate.reported.tolist() == [True]
    track_id = eng.tracks[0].track_id
    for t in range(8, 12):  # four frames without a detection
        eng.step(_frame(t, np.zeros((0, 4))))
    # found again 10 px short of where it would have walked: IoU with the prediction low,
    # with the last detection (four frames back) still > 0.3
    back = box + 7 * step + [14.0, 0, 0, 0]
    rec = eng.step(_frame(12, back))
    assert eng.num_targets == 1 and eng.tracks[0].track_id == track_id
    assert rec.info["detection"]["reupdated"].tolist() == [0]
    assert rec.plate.reported.tolist() == [False]  # one match in a row
    v_cx = eng.beliefs["box"].mean()[0, 4]
    assert 0.0 < v_cx < 6.0  # re-filtered along the gap: slowed, not reversed
    for t in range(13, 15):
        rec = eng.step(_frame(t, back + (t - 12) * step))
    assert rec.plate.reported.tolist() == [True]
    # a tentative track is kept through a miss (SORT would end it)
    eng = Engine(ocsort.build_graph(ocsort.Params(fps=30.0)), 0)
    for t in range(1, 6):
        eng.step(_frame(t, np.zeros((0, 4))))
    eng.step(_frame(6, box))
    eng.step(_frame(7, np.zeros((0, 4))))
    assert eng.num_targets == 1 and eng.tracks[0].track_id is None


def test_appearance_enters_the_association():
    """The appearance similarity is added to what a round maximises (the IoU gate stays):
    two replicas whose predictions overlap two detections almost equally are given the
    detection that looks like them; a replica's model is learned from the detections it is
    given, in frames with an image."""
    from pgm.inference.association import assign
    from pgm.inference.association_terms import AssociationInputs

    pred = np.array([[100.0, 100.0, 40.0, 100.0], [110.0, 100.0, 40.0, 100.0]])
    boxes = pred[::-1].copy()  # each detection sits on the other replica's prediction
    plans = DetectionAssociation("box", rounds=[{"iou": 0.3, "appearance": True}],
                                 appearance_weight=1.0).plans
    looks = np.array([[1.0, 0.37], [0.37, 1.0]])  # replica k looks like detection k
    plain = assign(AssociationInputs(pred, boxes, np.ones(2)), plans)  # no image, no term
    seen = assign(AssociationInputs(pred, boxes, np.ones(2), appearance=looks), plans)
    assert plain.cols[np.argsort(plain.rows)].tolist() == [1, 0]  # IoU 1 against 0.6
    assert seen.cols[np.argsort(seen.rows)].tolist() == [0, 1]  # 0.6 + 1 against 1 + 0.37
    far = assign(AssociationInputs(pred, boxes + [300.0, 0, 0, 0], np.ones(2),
                                   appearance=looks), plans)
    assert len(far.rows) == 0  # appearance alone never passes the IoU gate

    from pgm.models import ocsort_colour

    eng = Engine(ocsort_colour.build_graph(ocsort_colour.Params(fps=30.0)), 0)
    image = np.zeros((240, 320, 3), np.uint8)
    image[50:150, 100:140] = (0, 0, 255)
    for t in range(1, 4):
        ctx = _frame(t, [100.0, 50.0, 40.0, 100.0])
        eng.step(FrameContext(t, image, detections=ctx.detections))
    models = eng.replicas.state[0].get("box", TrackState).appearance
    assert len(models) == 1 and models[0].template is not None


@pytest.mark.parametrize("motion", ["cv", "cv3"])
def test_particle_motion_models_drive_the_same_core(motion):
    """``motion="cv"|"cv3"|"gpdm"``: the box state is particles moved by the motion model
    (Wang et al.'s (2008) idea on the classic cores); association (on the particles' mean) and the
    assigned detection's likelihood (a weight per particle) are the same factors. One
    person walking is one identity throughout, and the particles' mean follows the truth
    within a few pixels."""
    g = sort.build_graph(sort.Params(fps=30.0, motion=motion, num_particles=200))
    assert g.variables["box"].labels == ("cx", "cy", "w", "h")
    eng = Engine(g, 0)
    boxes = _walk(40, sigma=1.0)
    ids = set()
    for t, b in enumerate(boxes):
        rec = eng.step(_frame(t + 1, b))
        info = rec.plate
        ids |= set(info["ids"][info["reported"]].tolist())
    assert eng.num_targets == 1 and ids == {eng.tracks[0].track_id}
    est = eng.beliefs["box"].mean()[0]
    truth = boxes[-1, :2] + boxes[-1, 2:] / 2
    assert np.abs(est[:2] - truth).max() < 5.0
    with pytest.raises(ValueError, match="GPDM file"):
        sort.build_graph(sort.Params(motion="gpdm"))


def test_occlusion_gate_keeps_the_hidden_edges():
    """The part idea on a box: while a person's legs are hidden, the detector's box covers
    only the upper 60 %; with the occlusion gate that shortened bottom edge is taken as
    hidden and the target keeps its height (the edges seen still update it), without it
    the box shrinks to the visible part. (The hidden edge's uncertainty grows each frame
    it is not updated, so after a few frames the detection's edge passes the gate: here
    the fourth.)"""
    boxes = _walk(30, sigma=0.5)
    hidden = slice(15, 18)
    short = boxes.copy()
    short[hidden, 3] *= 0.6
    heights = {}
    for gate in (None, 3.0):
        p = sort.Params(fps=30.0, noise="scale", report="estimate", occlusion_gate=gate)
        eng = Engine(sort.build_graph(p), 0)
        for t, b in enumerate(short[:hidden.stop]):
            rec = eng.step(_frame(t + 1, b))
        heights[gate] = rec.plate.boxes[0, 3]
        if gate is not None:
            assert rec.info["detection"]["hidden_edges"] == 1
    true_h = boxes[hidden.stop - 1, 3]
    assert abs(heights[3.0] - true_h) < 0.1 * true_h
    assert heights[None] < 0.8 * true_h
    with pytest.raises(ValueError, match="corner state"):
        sort.build_graph(sort.Params(box_state="xysr", occlusion_gate=3.0))


def test_the_score_map_follows_what_is_known_of_the_detector():
    """Built for a video, the package's cores read the detector's score range: scores in
    [0, 1] are used as they are, scores outside through the logistic, and a detector
    without a score scale (background subtraction's fill fractions) has every detection
    taken as confident. The default reads quantiles of the video's scores (among the
    detections found again) unless told to read the detector's numbers."""
    from pgm.models import ocsort, ocsort_colour
    from pgm.models.config import VideoInfo

    for score_range, expected in (((0.1, 0.95), "none"), ((-2.0, 1.5), "logistic"),
                                  ((3.0, 140.0), "logistic"), (None, "constant")):
        g = ocsort.CONFIG.graph_for({}, VideoInfo(fps=25.0, score_range=score_range))
        assert g.factors["association"].score_map == expected
        # the default reads quantiles of the video's own scores, whatever their range...
        g = ocsort_colour.CONFIG.graph_for({}, VideoInfo(fps=25.0, score_range=score_range))
        assert g.factors["association"].score_map == (
            "constant" if score_range is None else "placed-over")
        # ... and with --scores detector the detector's numbers at OC-SORT's own split,
        # the default's presence round below it
        g = ocsort_colour.CONFIG.graph_for({"scores": "detector"},
                                           VideoInfo(fps=25.0, score_range=score_range))
        assert g.factors["association"].score_map == expected
        assert [(r["min_score"], r["max_score"]) for r in g.factors["association"].rounds] \
            == [(0.6, np.inf), (0.6, np.inf), (ocsort_colour.ABOVE_GATE, 0.6)]
    np.testing.assert_array_equal(map_scores(np.array([0.1, 0.4]), "constant"), [1.0, 1.0])


# ------------------------------------------------------------------------------------
# BoT-SORT and C-BIoU: round pools, score fusion, buffered IoU, first-frame activation,
# centre-only camera motion after the predict
# ------------------------------------------------------------------------------------
def _round(**kw):
    """A round as :class:`DetectionAssociation` runs it (its plan)."""
    return DetectionAssociation("box", rounds=[kw]).plans[0]


def _assign(pred, dets, scores, plans, **kw):
    from pgm.inference.association import assign
    from pgm.inference.association_terms import AssociationInputs

    return assign(AssociationInputs(pred, dets, np.asarray(scores, float)), plans, **kw)


def test_round_pools_fused_scores_and_buffers():
    """A round's ``"tracks"`` pool limits the replicas it may match; ``"fuse_score"``
    maximises and gates IoU × score; ``"buffer"`` matches boxes enlarged about their
    centres (boxes apart by a few pixels overlap)."""
    from pgm.inference.association import iou_matrix

    pred = np.array([[100.0, 100.0, 40.0, 100.0], [300.0, 100.0, 40.0, 100.0],
                     [500.0, 100.0, 40.0, 100.0]])
    confirmed = np.array([True, True, False])
    tracked = np.array([True, False, True])
    for pool, expected in (("all", [0, 1, 2]), ("confirmed", [0, 1]), ("tracked", [0]),
                           ("lost", [1]), ("tentative", [2])):
        a = _assign(pred, pred.copy(), np.ones(3), [_round(iou=0.3, tracks=pool)],
                   confirmed=confirmed, tracked=tracked)
        assert sorted(a.rows.tolist()) == expected, pool
        assert np.array_equal(a.rows, a.cols)
    with pytest.raises(ValueError, match="status"):
        _assign(pred, pred.copy(), np.ones(3), [_round(tracks="confirmed")])
    # one replica, two detections: the closer scores 0.3 (IoU ~0.82, fused ~0.25), the
    # other 0.9 (IoU ~0.6, fused ~0.54): IoU takes the first, IoU x score the second
    one = pred[:1]
    dets = np.array([[104.0, 100.0, 40.0, 100.0], [110.0, 100.0, 40.0, 100.0]])
    scores = np.array([0.3, 0.9])
    iou = iou_matrix(one, dets)[0]
    assert iou[0] > iou[1] and iou[0] * 0.3 < iou[1] * 0.9
    assert _assign(one, dets, scores, [_round(iou=0.2)]).cols.tolist() == [0]
    assert _assign(one, dets, scores, [_round(iou=0.2, fuse_score=True)]).cols.tolist() == [1]
    # the gate reads the product: IoU ~0.82 passes 0.5, IoU x 0.3 does not
    assert len(_assign(one, dets[:1], scores[:1], [_round(iou=0.5)]).rows) == 1
    assert len(_assign(one, dets[:1], scores[:1], [_round(iou=0.5, fuse_score=True)]).rows) == 0
    # buffered IoU: 5 px apart, no overlap; enlarged 1.6 times, IoU 7 / 57
    a, b = np.array([[100.0, 100.0, 20.0, 20.0]]), np.array([[125.0, 100.0, 20.0, 20.0]])
    assert iou_matrix(a, b)[0, 0] == 0.0
    assert len(_assign(a, b, np.ones(1), [_round(iou=0.1)]).rows) == 0
    got = _assign(a, b, np.ones(1), [_round(iou=0.1, buffer=0.3)])
    assert got.cols.tolist() == [0]
    np.testing.assert_allclose(iou_matrix(a * [1, 1, 1.6, 1.6], b * [1, 1, 1.6, 1.6]),
                               [[7.0 / 57.0]])


def test_botsort_rounds_and_life_cycle():
    """BoT-SORT's life cycle: the first frame's tracks are reported at once; later births
    (scores >= 0.7) at their second match, and end at their first miss before it; a
    low-score detection updates a track matched in the previous frame but not a lost one,
    which the confident round still finds under its identity."""
    from pgm.models import botsort

    eng = Engine(botsort.build_graph(botsort.Params(fps=30.0)), 0)
    a, b, c = ([x, 100.0, 40.0, 100.0] for x in (100.0, 400.0, 250.0))

    def step(t, boxes, scores):
        rec = eng.step(_frame(t, boxes, scores))
        info = rec.plate
        return {int(i) for i in info["ids"][info["reported"]]}

    first = step(1, [a, b], [0.9, 0.9])
    assert len(first) == 2 and eng.num_targets == 2  # reported in the first frame
    id_a, id_b = (int(t.track_id) for t in eng.tracks)
    assert step(2, [a, b], [0.9, 0.3]) == {id_a, id_b}  # b: the low round (tracked)
    assert step(3, [a], [0.9]) == {id_a}  # b missed: lost
    assert step(4, [a, b], [0.9, 0.3]) == {id_a}  # a lost track: not the low round
    assert eng.num_targets == 2 and eng.tracks[1].misses == 2
    assert step(5, [a, b], [0.9, 0.9]) == {id_a, id_b}  # the confident round finds it
    assert step(6, [a, b, c], [0.9, 0.9, 0.9]) == {id_a, id_b}  # c tentative
    assert eng.num_targets == 3
    step(7, [a, b], [0.9, 0.9])
    assert eng.num_targets == 2  # a tentative track ends at its first miss
    step(8, [a, b, c], [0.9, 0.9, 0.9])
    assert len(step(9, [a, b, c], [0.9, 0.9, 0.9])) == 3  # confirmed at its second match
    step(10, [a, b, [600.0, 100.0, 40.0, 100.0]], [0.9, 0.9, 0.65])
    assert eng.num_targets == 3  # confident (0.65 >= 0.6) but below activation 0.7
    # without the first-frame flag the first frame's tracks wait for their second match
    eng = Engine(botsort.build_graph(botsort.Params(fps=30.0, activate_first=False)), 0)
    assert step(1, [a, b], [0.9, 0.9]) == set()
    assert len(step(2, [a, b], [0.9, 0.9])) == 2


def _xcycwh_oracle(boxes, motions, sp=1 / 20, sv=1 / 160, sm=1 / 20):
    """BoT-SORT's Kalman filter as the ``trackers`` package writes it: state ``cx, cy,
    w, h`` and rates, scale-aware ``Q``, ``R``, ``P0`` from the current width and height,
    the camera's motion applied after the predict to the centre and its rate; the
    posterior means per frame."""
    F = np.eye(8)
    F[:4, 4:] = np.eye(4)

    def diag(w, h, a, b):
        return np.diag(np.array([a * w, a * h, a * w, a * h, b * w, b * h, b * w, b * h]) ** 2)

    x = np.r_[boxes[0], np.zeros(4)]
    P = diag(boxes[0, 2], boxes[0, 3], 2 * sp, 10 * sv)
    out = [x.copy()]
    for z, A in zip(boxes[1:], motions[1:], strict=True):
        Q = diag(x[2], x[3], sp, sv)
        x, P = F @ x, F @ P @ F.T + Q
        B = np.eye(8)
        B[:2, :2] = B[4:6, 4:6] = A[:, :2]
        x = B @ x + np.r_[A[:, 2], np.zeros(6)]
        P = B @ P @ B.T
        R = np.diag(np.array([sm * x[2], sm * x[3], sm * x[2], sm * x[3]]) ** 2)
        S = P[:4, :4] + R
        K = P[:, :4] @ np.linalg.inv(S)
        x = x + K @ (z - x[:4])
        P = (np.eye(8) - K[:, :4] @ np.eye(4, 8)[:, :4] @ np.eye(4, 8)) @ P
        out.append(x.copy())
    return np.array(out)


def test_botsort_corner_state_is_the_centre_and_size_filter_under_camera_motion():
    """BoT-SORT's state is centre and size; on the toolkit's corner state with the same
    scale-aware stds (``noise="scale"``) and the camera's motion moving the centre and
    its rate after the predict (``camera_warp="centre"``, ``camera_order="after"``), the
    posterior means are the package's filter's exactly (the covariances differ by ½ on the
    centre and 2 on the size, which no gain sees)."""
    from pgm.core.motion import linear_state_warp
    from pgm.models import botsort

    rng = np.random.default_rng(1)
    boxes = _walk(25, seed=2)
    cx = boxes.copy()
    cx[:, :2] += cx[:, 2:] / 2
    th = rng.normal(0.0, 0.004, len(boxes))
    s = 1.0 + rng.normal(0.0, 0.004, len(boxes))
    motions = [np.c_[sk * np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]),
                     rng.normal(0.0, 1.5, 2)] for t, sk in zip(th, s, strict=True)]
    eng = Engine(botsort.build_graph(botsort.Params(fps=30.0)), 0)
    means = []
    for t, (b, A) in enumerate(zip(boxes, motions, strict=True)):
        ctx = _frame(t + 1, b, [0.9])
        eng.step(FrameContext(t + 1, detections=ctx.detections,
                              camera_motion=None if t == 0 else A))
        assert eng.num_targets == 1
        m = eng.beliefs["box"].mean()[0]
        means.append(np.r_[(m[:2] + m[2:4]) / 2, m[2:4] - m[:2], (m[4:6] + m[6:]) / 2,
                           m[6:] - m[4:6]])
    np.testing.assert_allclose(means, _xcycwh_oracle(cx, motions), rtol=1e-9, atol=1e-8)
    # the centre-only warp of a corner state: the centre moves, the size does not
    A = motions[3]
    T, c = linear_state_warp(("x1", "y1", "x2", "y2"), A, sizes="keep")
    box = np.array([80.0, 10.0, 120.0, 90.0])
    moved = T @ box + c
    np.testing.assert_allclose((moved[:2] + moved[2:]) / 2, A[:, :2] @ [100.0, 50.0] + A[:, 2])
    np.testing.assert_allclose(moved[2:] - moved[:2], [40.0, 80.0])


def test_botsort_and_cbiou_settings_save_load_and_check():
    """The new round keys, the transition's camera settings and the life cycle's flag are
    saved with the graph and load to the same run; bad values are one-line ValueErrors."""
    from pgm.core.motion import linear_state_warp
    from pgm.core.plate import Lifecycle, Plate
    from pgm.factors.association import BoxTransition
    from pgm.models import botsort, cbiou

    f = DetectionAssociation("box", rounds=cbiou.rounds())
    p = json.loads(json.dumps(f.params()))
    assert p["rounds"][1] == {"iou": 0.5, "min_score": 0.1, "max_score": 0.6,
                              "tracks": "tracked", "buffer": 0.5}
    assert p["rounds"][0]["fuse_score"] is True and p["rounds"][2]["tracks"] == "tentative"
    assert DetectionAssociation("box", **p).rounds == f.rounds
    lc = Lifecycle(activate_first=True)
    assert Plate.from_dict(Plate("t", ["box"], lifecycle=lc).to_dict()).lifecycle == lc
    assert Lifecycle.from_dict({}).activate_first is False  # graphs saved before it
    boxes = _walk(12)
    for module in (botsort, cbiou):
        g = module.build_graph(module.Params(fps=30.0))
        loaded = FactorGraph.from_dict(json.loads(json.dumps(g.to_dict())))
        assert loaded == g
        tr = loaded.factors["transition:box"]
        assert (tr.camera, tr.camera_order) == ((("centre", "after") if module is botsort
                                                 else ("none", "before")))
        assert loaded.plates[0].lifecycle.activate_first is True
        runs = []
        A = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, -1.0]])
        for graph in (g, loaded):
            eng = Engine(graph, 0)
            for t, b in enumerate(boxes):
                ctx = _frame(t + 1, b)
                eng.step(FrameContext(t + 1, detections=ctx.detections, camera_motion=A))
            runs.append(eng.beliefs["box"].mean().copy())
        np.testing.assert_array_equal(runs[0], runs[1])
    with pytest.raises(ValueError, match="'tracks'"):
        DetectionAssociation("box", rounds=[{"tracks": "old"}])
    with pytest.raises(ValueError, match="'buffer'"):
        DetectionAssociation("box", rounds=[{"buffer": -0.1}])
    with pytest.raises(ValueError, match="round is a dict"):
        DetectionAssociation("box", rounds=[{"buffered": 0.3}])
    with pytest.raises(ValueError, match="camera must be"):
        botsort.build_graph(botsort.Params(camera_warp="wobble"))
    with pytest.raises(ValueError, match="camera_order"):
        BoxTransition("box", F=np.eye(8), Q=np.eye(8), camera_order="during")
    with pytest.raises(ValueError, match="activate_first"):
        Lifecycle(activate_first=1)
    with pytest.raises(ValueError, match="sizes"):
        linear_state_warp(("cx", "cy", "w", "h"), np.eye(2, 3), sizes="grow")
    with pytest.raises(ValueError, match=r"\(2, 3\)"):
        linear_state_warp(("cx", "cy", "w", "h"), np.eye(3))
    # a frame's map is kept (read-only) and is the same map when asked again
    B = np.array([[1.01, -0.02, 3.0], [0.02, 1.01, -1.5]])
    T, c = linear_state_warp(("cx", "cy", "w", "h"), B)
    assert linear_state_warp(["cx", "cy", "w", "h"], B.copy())[0] is T
    assert not T.flags.writeable and not c.flags.writeable
    np.testing.assert_allclose(T[:2, :2], B[:, :2])
    np.testing.assert_allclose(np.diag(T)[2:], np.sqrt(np.linalg.det(B[:, :2])))


def test_botsort_score_threshold_moves_the_split_and_keeps_the_floor():
    """``--score-threshold P`` sets the confident detections' split and the activation at
    ``P``; the low band keeps its floor (0.1) and is dropped when ``P`` is not above it."""
    from pgm.models import botsort, cbiou

    r = botsort.with_score_threshold(botsort.rounds(), 0.5)
    assert [(x.get("min_score"), x.get("max_score")) for x in r] == [(0.5, None), (0.1, 0.5),
                                                                       (0.5, None)]
    assert len(botsort.with_score_threshold(botsort.rounds(), 0.05)) == 2
    g = cbiou.build_graph(cbiou.Params(score_threshold=0.4, score_map="learned"))
    rounds = g.factors["association"].rounds
    assert [x["min_score"] for x in rounds] == [0.4, 0.1, 0.4] and rounds[1]["buffer"] == 0.5
    assert g.plates[0].lifecycle.birth_min_score == 0.4
    with pytest.raises(ValueError, match="score_threshold"):
        botsort.build_graph(botsort.Params(score_threshold=2.0, score_map="learned"))


def test_botsort_camera_motion_estimate():
    """``CameraMotionEstimator(method="botsort")``: BoT-SORT's sparse optical flow on the
    halved grey frame finds an image shift, and with ``"on"`` gives every frame a motion,
    a still camera's too (the toolkit's checked fit gives that frame none)."""
    import cv2

    from pgm.observation.camera_motion import CameraMotionEstimator

    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8), (5, 5), 1.5)
    shifted = cv2.warpAffine(image, np.array([[1.0, 0, 6.0], [0, 1.0, -4.0]]), (320, 240),
                             borderMode=cv2.BORDER_REFLECT)
    est = CameraMotionEstimator("on", method="botsort")
    assert est(image) is None  # the first frame
    A = est(shifted)
    np.testing.assert_allclose(A[:, 2], [6.0, -4.0], atol=0.5)
    np.testing.assert_allclose(A[:, :2], np.eye(2), atol=0.01)
    still = est(shifted)
    assert still is not None and np.abs(still - np.eye(2, 3)).max() < 0.1
    checked = CameraMotionEstimator("on")
    checked(shifted)
    assert checked(shifted) is None
    with pytest.raises(ValueError, match="method"):
        CameraMotionEstimator("on", method="orb")
    with pytest.raises(ValueError, match="downscale"):
        CameraMotionEstimator("on", method="botsort", downscale=0)


def test_reference_frame_rate_converts_per_frame_constants_to_seconds():
    """``reference_fps``: at the reference rate nothing changes; at a third of it the
    windows of frames are a third as long and the Kalman noise is that of the same
    continuous-time random walk — a box coordinate's variance per video frame ``τ`` times
    the reference frame's, a rate's (per video frame, ``τ`` times as large) ``τ³``."""
    from dataclasses import replace

    from pgm.models import ocsort

    for p in (sort.Params(), ocsort.Params(), sort.Params(noise="scale")):
        same = sort.build_graph(replace(p, fps=30.0, reference_fps=30.0))
        plain = sort.build_graph(replace(p, fps=30.0))
        for name, f in plain.factors.items():
            assert json.dumps(f.params(), default=str) == \
                json.dumps(same.factors[name].params(), default=str)
        assert plain.plates[0].lifecycle == same.plates[0].lifecycle
    tau = 3.0
    for p in (sort.Params(), ocsort.Params()):
        ref = sort.build_graph(replace(p, fps=30.0))
        slow = sort.build_graph(replace(p, fps=10.0, reference_fps=30.0))
        q_ref = np.diag(ref.factors["transition:box"].Q)
        q_slow = np.diag(slow.factors["transition:box"].Q)
        np.testing.assert_allclose(q_slow[:4], tau * q_ref[:4])
        np.testing.assert_allclose(q_slow[4:], tau ** 3 * q_ref[4:])
        # a rate's variance per second after one reference second of steps is the same
        per_second_ref = 30 * q_ref[4:] * 30.0 ** 2
        per_second_slow = 10 * q_slow[4:] * 10.0 ** 2
        np.testing.assert_allclose(per_second_slow, per_second_ref)
        np.testing.assert_allclose(np.diag(slow.factors["prior:box"].cov)[4:],
                                   tau ** 2 * np.diag(ref.factors["prior:box"].cov)[4:])
        lc_ref, lc_slow = ref.plates[0].lifecycle, slow.plates[0].lifecycle
        assert lc_slow.confirm_hits == max(1, round(lc_ref.confirm_hits / tau)) == 1
        assert slow.factors["association"].delta_t == 1
        assert lc_slow.max_lost == 10  # the lost buffer was already in seconds
    scaled = sort.build_graph(sort.Params(noise="scale", fps=10.0, reference_fps=30.0))
    base = sort.build_graph(sort.Params(noise="scale"))
    np.testing.assert_allclose(scaled.factors["transition:box"].relative_std,
                               base.factors["transition:box"].relative_std
                               * np.array([tau ** 0.5] * 4 + [tau ** 1.5] * 4))
    np.testing.assert_allclose(scaled.factors["prior:box"].relative_std,
                               base.factors["prior:box"].relative_std
                               * np.array([1.0] * 4 + [tau] * 4))
    with pytest.raises(ValueError, match="reference_fps"):
        sort.build_graph(sort.Params(reference_fps=float("nan")))


def test_noise_per_detection_keeps_the_step_and_converts_only_the_rates_units():
    """``noise_per="detection"``: at a third of the reference rate a box coordinate's
    process variance is the reference frame's and a rate's (per video frame, ``τ`` times
    as large) ``τ²`` times it — the same step in the video's units — with the windows of
    frames converted as with ``"second"``; an unknown value is an error."""
    from dataclasses import replace

    tau = 3.0
    for p in (sort.Params(), sort.Params(box_state="xysr")):
        ref = sort.build_graph(replace(p, fps=30.0))
        slow = sort.build_graph(replace(p, fps=10.0, reference_fps=30.0,
                                        noise_per="detection"))
        per_second = sort.build_graph(replace(p, fps=10.0, reference_fps=30.0))
        q_ref = np.diag(ref.factors["transition:box"].Q)
        q_slow = np.diag(slow.factors["transition:box"].Q)
        d = len(q_ref) // 2 if p.box_state == "xyxy" else 4
        np.testing.assert_allclose(q_slow[:d], q_ref[:d])
        np.testing.assert_allclose(q_slow[d:], tau ** 2 * q_ref[d:])
        np.testing.assert_allclose(np.diag(slow.factors["prior:box"].cov),
                                   np.diag(per_second.factors["prior:box"].cov))
        assert slow.plates[0].lifecycle == per_second.plates[0].lifecycle
        assert slow.factors["association"].delta_t == per_second.factors["association"].delta_t
    scaled = sort.build_graph(sort.Params(noise="scale", fps=10.0, reference_fps=30.0,
                                          noise_per="detection"))
    base = sort.build_graph(sort.Params(noise="scale"))
    np.testing.assert_allclose(scaled.factors["transition:box"].relative_std,
                               base.factors["transition:box"].relative_std
                               * np.array([1.0] * 4 + [tau] * 4))
    with pytest.raises(ValueError, match="noise_per"):
        sort.build_graph(sort.Params(noise_per="frame"))


def test_noise_per_displacement_keeps_every_step_and_converts_the_initial_speed():
    """``noise_per="displacement"``: at a third of the reference rate every process
    variance (a coordinate's, a rate's) is the reference frame's — a displacement of so
    many pixels per detection — while a rate's initial variance, a speed, is ``τ²`` times
    it as with the other two; the scale-aware rate std is unchanged too."""
    from dataclasses import replace

    tau = 3.0
    for p in (sort.Params(), sort.Params(box_state="xysr")):
        ref = sort.build_graph(replace(p, fps=30.0))
        slow = sort.build_graph(replace(p, fps=10.0, reference_fps=30.0,
                                        noise_per="displacement"))
        per_detection = sort.build_graph(replace(p, fps=10.0, reference_fps=30.0,
                                                 noise_per="detection"))
        np.testing.assert_allclose(slow.factors["transition:box"].Q,
                                   ref.factors["transition:box"].Q)
        p0_slow, p0_ref = (np.diag(g.factors["prior:box"].cov) for g in (slow, ref))
        np.testing.assert_allclose(p0_slow, np.diag(per_detection.factors["prior:box"].cov))
        np.testing.assert_allclose(p0_slow[:4], p0_ref[:4])
        np.testing.assert_allclose(p0_slow[4:], tau ** 2 * p0_ref[4:])
    scaled = sort.build_graph(sort.Params(noise="scale", fps=10.0, reference_fps=30.0,
                                          noise_per="displacement"))
    base = sort.build_graph(sort.Params(noise="scale"))
    np.testing.assert_allclose(scaled.factors["transition:box"].relative_std,
                               base.factors["transition:box"].relative_std)


def test_no_birth_on_a_detection_a_track_explains():
    """``birth_iou``: a detector's second, weaker box on a person (IoU 0.43 with the first)
    starts a second identity in the package's cores (``birth_iou=1``), none with the
    default's 0.3; a person elsewhere is still born, and of two overlapping free detections
    in one frame only the higher-scored starts a track."""
    walk = _walk(n=20)
    far = np.array([400.0, 100.0, 40.0, 100.0])

    def identities(birth_iou):
        eng = Engine(sort.build_graph(sort.Params(birth_iou=birth_iou)), 0)
        ids = set()
        for t, box in enumerate(walk, start=1):
            dets = [box, box + [10.0, 20.0, 0.0, 0.0]] + ([far] if t > 5 else [])
            rec = eng.step(_frame(t, dets, [0.9, 0.5] + ([0.9] if t > 5 else [])))
            ids |= {int(i) for i in rec.plate.ids[rec.plate.reported]}
        return len(ids), eng.num_targets

    assert identities(1.0) == (3, 3)  # the duplicate is a track of its own
    assert identities(0.3) == (2, 2)  # the person and the one far away
    # first frame, no track yet: the two overlapping boxes start one track
    eng = Engine(sort.build_graph(sort.Params(birth_iou=0.3)), 0)
    eng.step(_frame(1, [walk[0], walk[0] + [10.0, 20.0, 0.0, 0.0]], [0.5, 0.9]))
    assert eng.num_targets == 1
    np.testing.assert_allclose(eng.tracks[0].state[:2], walk[0][:2] + [10.0, 20.0]
                               + walk[0][2:] / 2)


@pytest.mark.parametrize("explain, b_score, kept", [
    ("none", 0.5, True), ("prediction", 0.5, False), ("prediction", 0.95, False),
    ("detection", 0.5, False), ("detection", 0.95, True)])
def test_a_tentative_track_on_a_detection_a_confirmed_one_explains(explain, b_score, kept):
    """``explain_tentative``: a box born beside a confirmed person (IoU 0.18, so born)
    moves onto it (IoU 0.33 with the person's box and prediction): removed while
    tentative under ``"prediction"``; under ``"detection"`` only if it is the weaker of
    the two boxes; confirmed under ``"none"``."""
    a = np.array([100.0, 100.0, 40.0, 100.0])
    eng = Engine(sort.build_graph(sort.Params(birth_iou=0.3, explain_tentative=explain)), 0)
    for t in range(1, 4):
        eng.step(_frame(t, [a]))
    for t, x in ((4, 128.0), (5, 120.0), (6, 120.0)):
        rec = eng.step(_frame(t, [a, [x, 100.0, 40.0, 100.0]], [0.9, b_score]))
    assert eng.num_targets == (2 if kept else 1)
    assert int(rec.plate.reported.sum()) == (2 if kept else 1)


def test_explain_tentative_is_checked_and_saved():
    from pgm.core.plate import Lifecycle

    with pytest.raises(ValueError, match="explain_tentative must be one of"):
        Lifecycle(explain_tentative="both")
    lc = Lifecycle(explain_tentative="detection")
    assert Lifecycle.from_dict(lc.to_dict()) == lc


def test_a_gap_filled_when_the_track_is_found_again():
    """``fill_gaps``: a confirmed track missed for two frames and found again reports the
    two missed frames (``Targets.filled``), their boxes on the line between the boxes it
    reported before and after the gap, once it has been matched ``min_hits`` frames in a
    row since (``fill_after=1``: at the match that closed the gap); a gap whose track
    misses again before then, a longer gap than ``fill_gaps`` frames, and a track never
    found again fill nothing."""
    from pgm.core.readout import readout

    box = np.array([100.0, 100.0, 40.0, 100.0])
    step = np.array([6.0, 3.0, 0.0, 0.0])
    # gaps of 2 frames closed at 7 (missed again at 9) and at 11 (then matched 12, 13),
    # one of 3 frames closed at 17
    seen = [1, 2, 3, 4, 7, 8, 11, 12, 13, 17]

    def run(**kw):
        eng = Engine(sort.build_graph(sort.Params(fps=10.0, fill_gaps=0.2, report="detection",
                                                  **kw)), 0)
        assert eng.graph.plates[0].lifecycle.fill_gaps == 2  # 0.2 s at 10 frames/s
        filled = {}
        for t in range(1, 19):
            dets = [box + t * step] if t in seen else np.zeros((0, 4))
            out = readout(eng.graph, eng.step(_frame(t, dets)))
            if out.filled is not None:
                filled[t] = out.filled
        return filled

    filled = run()  # min_hits = 3 matches in a row since the gap
    assert list(filled) == [13]
    late = filled[13]
    assert late.frames.tolist() == [9, 10] and len(set(late.ids.tolist())) == 1
    np.testing.assert_allclose(late.boxes, [box + 9 * step, box + 10 * step])
    at_once = run(fill_after=1)
    assert list(at_once) == [7, 11]
    assert at_once[7].frames.tolist() == [5, 6] and at_once[11].frames.tolist() == [9, 10]
    np.testing.assert_allclose(at_once[7].boxes, [box + 5 * step, box + 6 * step])
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="fill_after"):
            sort.build_graph(sort.Params(fill_gaps=0.2, fill_after=bad))
    with pytest.raises(ValueError, match="fill_gaps"):
        sort.build_graph(sort.Params(fill_gaps=-1.0))


def test_a_gap_filled_in_the_camera_s_world():
    """A still object seen by a camera that pans unevenly (0, then 30 px, then 0 px a frame
    over a two-frame gap): the filled boxes follow the camera — the box of frame 5 where
    the object was then, that of frame 6 moved by the pan — not the image's straight
    line between the two reported boxes."""
    from pgm.core.readout import readout

    box = np.array([100.0, 100.0, 40.0, 100.0])
    pans = {t: 10.0 for t in range(2, 13)} | {5: 0.0, 6: 30.0, 7: 0.0}
    x = {1: 0.0}
    for t in range(2, 13):
        x[t] = x[t - 1] + pans[t]
    eng = Engine(sort.build_graph(sort.Params(fps=10.0, fill_gaps=0.2, report="detection",
                                              fill_after=1)), 0)
    filled = {}
    for t in range(1, 13):
        dets = np.asarray([box + [x[t], 0, 0, 0]] if t not in (5, 6) else []).reshape(-1, 4)
        ctx = FrameContext(t, detections=Detections(dets, np.full(len(dets), 0.9)),
                           camera_motion=np.array([[1.0, 0, pans.get(t, 0.0)], [0, 1, 0]]))
        out = readout(eng.graph, eng.step(ctx))
        if out.filled is not None:
            filled[t] = out.filled
    assert list(filled) == [7] and filled[7].frames.tolist() == [5, 6]
    np.testing.assert_allclose(filled[7].boxes, [box + [x[5], 0, 0, 0], box + [x[6], 0, 0, 0]],
                               atol=1e-9)


def test_a_confirmed_track_reports_the_frames_it_was_tentative_in():
    """``fill_births``: a track confirmed at its third match reports its first two frames
    then, with the boxes it had (the detections, ``report="detection"``); without it those
    frames are never reported. ``count_hits="detections"`` keeps the counts of matches
    at any frame rate while the momentum window is still converted."""
    from pgm.core.readout import readout

    box = np.array([100.0, 100.0, 40.0, 100.0])
    step = np.array([6.0, 3.0, 0.0, 0.0])

    def run(**kw):
        eng = Engine(sort.build_graph(sort.Params(fps=10.0, report="detection", **kw)), 0)
        rows = []
        for t in range(1, 7):
            out = readout(eng.graph, eng.step(_frame(t, [box + t * step])))
            f, i, b, _ = out.rows(t)
            rows += [(int(fr), int(k), *bb) for fr, k, bb in zip(f, i, b, strict=True)]
        return rows

    plain, births = run(), run(fill_births=True)
    assert [r[0] for r in plain] == [3, 4, 5, 6]
    assert [r[0] for r in births] == [3, 1, 2, 4, 5, 6]  # frames 1, 2 written at 3
    np.testing.assert_allclose([r[2:] for r in births[1:3]], [box + step, box + 2 * step])
    assert len({r[1] for r in births}) == 1
    from dataclasses import replace

    q = sort.at_frame_rate(replace(sort.Params(), reference_fps=30.0, fps=10.0,
                                   count_hits="detections", recover_hits=3))
    assert (q.min_hits, q.recover_hits, q.delta_t) == (3, 3, 1)
    with pytest.raises(ValueError, match="count_hits"):
        sort.build_graph(sort.Params(count_hits="frames"))
