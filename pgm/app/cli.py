"""The ``pgm`` command line.

::

    pgm track SOURCE [--model single-object|colour-pf|part-graph] (--init X,Y,W,H | --gt FILE)
              --out DIR
              [--parts 2|3] [--fusion mixture|product] [--particles N] [--seed S]
              [--no-video] [--show-particles]
    pgm track SOURCE --model phd|vb-phd [--detections FILE | --detector public|mog2]
              --out DIR [--gt FILE]
    pgm eval --gt FILE --pred DIR/tracks.txt [--json]
    pgm graph MODEL [--parts 2|3] --out FILE.{png,svg,pdf,dot}
    pgm learn dbn --train SEQ [SEQ ...] --out FILE.npz
    pgm demo --out DIR

Bad input (a missing or corrupt video, a malformed box or ground-truth file, a bad
parameter) gets a one-line ``pgm: error: ...`` and exit code 2, never a traceback.
The CLI sits on top of everything and may import :mod:`pgm.models`: imports otherwise go
one way, ``models → inference → pgm``, and a test of the code base enforces it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from pgm.core.errors import InputError

__all__ = ["main", "build_parser", "parse_box"]

EXIT_BAD_INPUT = 2


def parse_box(text: str) -> np.ndarray:
    """Parse ``"X,Y,W,H"`` (top-left corner and size, 1-based like MOT/OTB files)."""
    parts = [p for p in text.replace(" ", "").split(",") if p]
    try:
        vals = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"--init must be four numbers X,Y,W,H, got {text!r}") from None
    if vals.shape != (4,) or not np.all(np.isfinite(vals)):
        raise InputError(f"--init must be four finite numbers X,Y,W,H, got {text!r}")
    if vals[2] <= 0 or vals[3] <= 0:
        raise InputError(f"--init box {text!r} has zero or negative area")
    vals[:2] -= 1.0  # 1-based file convention -> 0-based internal
    return vals


def _int_at_least(name: str, low: int):
    """An argparse type: an integer ``>= low``, with a one-line message naming ``name``."""
    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if v < low:
            what = "a positive integer" if low == 1 else f"at least {low}"
            raise argparse.ArgumentTypeError(f"{name} must be {what}, got {v}")
        return v

    return conv


def _positive_int(name: str):
    return _int_at_least(name, 1)


_nonneg_int = _int_at_least("seed", 0)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``pgm track: error: ...``), exit 2."""

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {' '.join(message.split())} "
                                  f"(see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pgm``."""
    from pgm.models import MODELS

    p = _Parser(
        prog="pgm", description="Visual trackers declared as factor graphs, run by one engine.")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    t = sub.add_parser("track", help="track an object through a video or image sequence")
    t.add_argument("source", help="video file, image folder, MOTChallenge or OTB sequence folder")
    t.add_argument("--model", default=None,
                   help=f"model name ({', '.join(sorted(MODELS))}) or a saved model .json; "
                        f"default: single-object (the correlation-filter tracker), or "
                        f"vb-phd when --detections/--detector is given")
    init = t.add_mutually_exclusive_group()
    init.add_argument("--init", help="box in frame 1: X,Y,W,H (top-left, 1-based like MOT/OTB)")
    t.add_argument("--gt", help="ground-truth file (initialises from frame 1 when --init is "
                                "absent; writes metrics.json)")
    t.add_argument("--out", required=True, help="output folder")
    t.add_argument("--particles", type=_positive_int("--particles"), default=None,
                   help="particles per variable (default: the model's)")
    _model_options(t)
    t.add_argument("--seed", type=_nonneg_int, default=0)
    t.add_argument("--no-video", action="store_true", help="do not write annotated.mp4")
    t.add_argument("--show-particles", action="store_true",
                   help="draw particles in the annotated video")
    t.add_argument("--max-frames", type=_positive_int("--max-frames"), default=None)
    t.add_argument("--camera-motion", choices=("auto", "on", "off"), default="auto",
                   help="global-motion compensation of every target's prediction: auto (on "
                        "frames where the camera moves, default), on, off")
    t.add_argument("--detections", help="phd/vb-phd: a MOTChallenge det.txt to use as "
                                        "measurements")
    t.add_argument("--dbn", help="phd/vb-phd: a DBN person likelihood trained by "
                                 "'pgm learn dbn' (multiplies the detection terms)")
    t.add_argument("--scale-aware", action="store_true",
                   help="phd/vb-phd: track each box's scale; noise in units of each target's "
                        "own height (experimental: see the README's MOT table)")
    t.add_argument("--per-track-noise", action="store_true",
                   help="vb-phd: one noise belief per track instead of one shared")
    t.add_argument("--scores", choices=("off", "mixture"), default=None,
                   help="phd/vb-phd: detection scores in the measurement model: 'mixture' "
                        "(per-detection clutter from a two-class score mixture fitted on the "
                        "video; low-score detections only extend tracks) or 'off' "
                        "(score-blind); default: the video default")
    t.add_argument("--detector", default=None,
                   help="phd/vb-phd: 'public' (the sequence's det/det.txt, default), "
                        "'public:MIN_SCORE' or 'mog2' (background subtraction)")
    t.add_argument("--quiet", action="store_true", help="no progress bar")

    e = sub.add_parser("eval", help="score a tracks.txt against ground truth")
    e.add_argument("--gt", required=True, help="ground truth (OTB, MILTrack or MOT gt.txt)")
    e.add_argument("--pred", required=True, help="tracks.txt written by pgm track")
    e.add_argument("--json", action="store_true", help="print JSON instead of a table")

    g = sub.add_parser("graph", help="draw a model's factor graph")
    g.add_argument("model", help=f"model name ({', '.join(sorted(MODELS))}) or a model .json")
    g.add_argument("--out", required=True, help="FILE.png, .svg, .pdf or .dot")
    _model_options(g)

    lp = sub.add_parser("learn", help="learn model parameters from annotated sequences")
    lsub = lp.add_subparsers(dest="what", required=True, parser_class=_Parser)
    ld = lsub.add_parser("dbn", help="train the deep-belief-network person likelihood")
    ld.add_argument("--train", nargs="+", required=True,
                    help="MOTChallenge sequence folders with gt/gt.txt (never the one you "
                         "will evaluate on)")
    ld.add_argument("--out", required=True, help="output .npz file")
    ld.add_argument("--every", type=_positive_int("--every"), default=3,
                    help="use every K-th annotated frame")
    ld.add_argument("--seed", type=_nonneg_int, default=0)
    ld.add_argument("--epochs", type=_positive_int("--epochs"), default=40,
                    help="fine-tuning epochs")

    d = sub.add_parser("demo", help="render a synthetic scene, track it, write every output")
    d.add_argument("--out", required=True, help="output folder")
    d.add_argument("--seed", type=_nonneg_int, default=0)
    d.add_argument("--frames", type=_positive_int("--frames"), default=90)
    d.add_argument("--particles", type=_positive_int("--particles"), default=100)
    d.add_argument("--quiet", action="store_true")
    return p


def _model_options(p: argparse.ArgumentParser) -> None:
    """Options that set a model config's ``Params`` fields (used where the model has them)."""
    p.add_argument("--parts", type=_positive_int("--parts"), default=None,
                   help="part-graph: number of bands (2 for a person, 3 for a face)")
    p.add_argument("--split", choices=("rows", "cols"), default=None,
                   help="part-graph: horizontal (rows, default) or vertical bands")
    p.add_argument("--topology", choices=("chain", "full"), default=None,
                   help="part-graph: couplings between neighbours (chain) or all pairs")
    p.add_argument("--fusion", choices=("mixture", "product"), default=None,
                   help="part-graph: particle-BP fusion rule (default mixture)")
    p.add_argument("--appearance", default=None, metavar="CUE[+CUE...]",
                   help="single-object/colour-pf/part-graph: likelihood cues per node, "
                        "multiplied: colour (one colour histogram), fragments (3x3 colour "
                        "fragments, median), gradient (oriented gradients), gmm (GMM-KL), "
                        "rings (rotation-invariant), contrast (foreground/background colour "
                        "log-odds), template (grey NCC; sees scale), cf (online correlation "
                        "filter; the default's cue); options in parentheses, e.g. "
                        "'cf(lam=40,padding=2)+template'")
    p.add_argument("--scale-noise", type=float, default=None,
                   help="single-object/colour-pf/part-graph: std of a shared log-scale step "
                        "per frame (0: fixed size; use with a cue that sees scale)")


# -- commands ---------------------------------------------------------------------------
def _load_model_graph(model: str, init_box_cxcywh: np.ndarray, num_particles: int | None,
                      args: argparse.Namespace | None = None):
    import dataclasses

    from pgm.core.graph import FactorGraph
    from pgm.models import get_model

    if model.endswith(".json"):
        return FactorGraph.load(model)
    module = get_model(model)
    fields = {f.name for f in dataclasses.fields(module.Params)}
    kwargs = {"init_box": tuple(float(v) for v in init_box_cxcywh)}
    if num_particles is not None:
        kwargs["num_particles"] = num_particles
    options = {"parts": "n_parts", "split": "split", "topology": "topology",
               "fusion": "fusion", "appearance": "appearance", "scale_noise": "scale_noise"}
    for opt, field in options.items():
        value = getattr(args, opt, None) if args is not None else None
        if value is None:
            continue
        if field not in fields:
            raise InputError(f"--{opt} does not apply to model {model!r}")
        kwargs[field] = value
    return module.build_graph(module.Params(**kwargs))


def _check_box_in_image(box_xywh: np.ndarray, size: tuple[int, int]) -> None:
    w_img, h_img = size
    x, y, w, h = box_xywh
    if x >= w_img or y >= h_img or x + w <= 0 or y + h <= 0:
        raise InputError(f"initial box ({x + 1:g},{y + 1:g},{w:g},{h:g}) lies outside the "
                         f"{w_img}x{h_img} image")


def _print_metrics(metrics: dict, stream=None) -> None:
    stream = sys.stdout if stream is None else stream
    rows = [("frames scored", f"{metrics['n_frames']}"),
            ("success AUC", f"{metrics['success_auc']:.3f}"),
            ("precision@20px", f"{metrics['precision_at_20']:.3f}"),
            ("mean IoU", f"{metrics['mean_iou']:.3f}"),
            ("mean centre error (px)", f"{metrics['mean_centre_error']:.2f}")]
    if "fps" in metrics:
        rows.append(("frames per second", f"{metrics['fps']:.1f}"))
    width = max(len(r[0]) for r in rows)
    for k, v in rows:
        print(f"{k:<{width}}  {v}", file=stream)


MULTI_TARGET_MODELS = ("phd", "vb-phd")


def cmd_track_multi(args, source) -> int:
    from pgm.app.runner import track_multi
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_mot
    from pgm.models import get_model
    from pgm.models.phd import video_params
    from pgm.observation.detections import PublicDetections, make_detector

    if args.init is not None:
        raise InputError(f"--init does not apply to the multi-target model {args.model!r}")
    if args.detections is not None and args.detector is not None:
        raise InputError("give either --detections FILE or --detector SPEC, not both")
    if args.detections is not None:
        detector = PublicDetections(args.detections)
    else:
        detector = make_detector(args.detector or "public", source)
    gt_path = args.gt or source.gt_path
    gt = load_mot(gt_path, kind="gt") if gt_path is not None else None
    module = get_model(args.model)
    width, height = source.size
    kwargs = {}
    if args.particles is not None:
        kwargs["particles_per_target"] = args.particles
    if args.per_track_noise:
        if args.model != "vb-phd":
            raise InputError("--per-track-noise applies to vb-phd only")
        kwargs["per_track_noise"] = True
    table = getattr(detector, "table", None)  # public detections: their median height
    if table is not None and len(table):
        kwargs["typical_height"] = float(np.median(table.boxes[:, 3]))
    if args.scale_aware:
        kwargs["scale_aware"] = True
    if args.scores is not None:
        kwargs["score_model"] = args.scores
    graph = module.build_graph(video_params(module.Params, width, height, source.fps,
                                            **kwargs))
    if args.dbn is not None:
        from pgm.observation.appearance.dbn import DBNLikelihood

        graph = graph.with_factors(DBNLikelihood("targets", model=args.dbn,
                                                 name="appearance:dbn"),
                                   name=graph.name + "+dbn")
    result = track_multi(source, graph, detector, rng=as_generator(args.seed), out_dir=args.out,
                         gt=gt, write_video=not args.no_video, show_particles=args.show_particles,
                         progress=not args.quiet, max_frames=args.max_frames,
                         camera_motion=args.camera_motion)
    print(f"tracked {result.n_frames} frames at {result.fps:.1f} frames/s (inference only; "
          f"detector {result.n_frames / max(result.detector_seconds, 1e-9):.0f} frames/s) -> "
          f"{Path(args.out) / 'tracks.txt'}")
    if result.metrics is not None:
        _print_mot_metrics(result.metrics)
    return 0


def _print_mot_metrics(m: dict, stream=None) -> None:
    stream = sys.stdout if stream is None else stream
    keys = [("MOTA", "mota"), ("IDF1", "idf1"), ("HOTA", "hota"), ("MOTP (IoU)", "motp"),
            ("ID switches", "id_switches"), ("FP", "fp"), ("FN", "fn"),
            ("OSPA(50,1) px", "ospa_50_1"), ("OSPA(100,2) px", "ospa_100_2"),
            ("OSPA2(50,1) px", "ospa2"), ("|cardinality error|", "mean_abs_cardinality_error"),
            ("frames per second", "fps")]
    width = max(len(k) for k, _ in keys)
    for label, key in keys:
        if key in m:
            v = m[key]
            print(f"{label:<{width}}  {v:.3f}" if isinstance(v, float) else
                  f"{label:<{width}}  {v}", file=stream)


def cmd_track(args) -> int:
    from pgm.app.runner import init_box_from_gt, track
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_single_gt
    from pgm.io.video import open_source

    source = open_source(args.source)
    if args.model is None:
        from pgm.models import DEFAULT_SINGLE_OBJECT

        multi = args.detections is not None or args.detector is not None
        args.model = "vb-phd" if multi else DEFAULT_SINGLE_OBJECT
        if not args.quiet:
            print(f"pgm: using model {args.model} (no --model given)", file=sys.stderr)
    if args.model in MULTI_TARGET_MODELS:
        return cmd_track_multi(args, source)
    if args.detections is not None or args.detector is not None:
        raise InputError(f"--detections/--detector apply to {', '.join(MULTI_TARGET_MODELS)}, "
                         f"not to {args.model!r}")
    gt = None
    gt_path = args.gt
    if gt_path is None and args.init is None and source.gt_path is not None:
        gt_path = str(source.gt_path)
        print(f"pgm: using the sequence's ground truth {gt_path}", file=sys.stderr)
    if gt_path is not None:
        gt = load_single_gt(gt_path)
    if args.init is not None:
        box_xywh = parse_box(args.init)
    elif gt is not None:
        c = init_box_from_gt(gt, 1)
        box_xywh = np.array([c[0] - c[2] / 2, c[1] - c[3] / 2, c[2], c[3]])
    else:
        raise InputError("give the initial box with --init X,Y,W,H or a ground truth with --gt")
    _check_box_in_image(box_xywh, source.size)
    init_c = np.array([box_xywh[0] + box_xywh[2] / 2, box_xywh[1] + box_xywh[3] / 2,
                       box_xywh[2], box_xywh[3]])
    graph = _load_model_graph(args.model, init_c, args.particles, args)
    result = track(source, graph, rng=as_generator(args.seed), out_dir=args.out, gt=gt,
                   num_particles=args.particles, write_video=not args.no_video,
                   show_particles=args.show_particles, progress=not args.quiet,
                   max_frames=args.max_frames, camera_motion=args.camera_motion)
    print(f"tracked {len(result.frames)} frames at {result.fps:.1f} frames/s "
          f"(inference only) -> {Path(args.out) / 'tracks.txt'}")
    if result.metrics is not None:
        _print_metrics({**result.metrics, "fps": result.fps})
    return 0


def cmd_eval(args) -> int:
    from pgm.evaluation.single_object import single_object_metrics
    from pgm.io.annotations import detect_gt_format, load_mot, load_single_gt, load_tracks

    pred = load_tracks(args.pred)
    if detect_gt_format(args.gt) == "mot":
        gt_table = load_mot(args.gt, kind="gt")
        if np.unique(gt_table.ids).size > 1 or np.unique(pred.ids).size > 1:
            from pgm.evaluation.mot import evaluate_mot_files

            metrics = evaluate_mot_files(args.gt, args.pred)
            if args.json:
                print(json.dumps(metrics, indent=1))
            else:
                _print_mot_metrics(metrics)
            return 0
    gt = load_single_gt(args.gt)
    ids = np.unique(pred.ids)
    if ids.size > 1:
        raise InputError(f"{args.pred} has {ids.size} identities; single-object evaluation "
                         f"needs one")
    metrics = single_object_metrics(gt, pred.frames, pred.boxes)
    if args.json:
        print(json.dumps(metrics, indent=1))
    else:
        _print_metrics(metrics)
    return 0


def cmd_graph(args) -> int:
    out = Path(args.out)
    if out.suffix.lower() not in (".png", ".svg", ".pdf", ".dot"):
        raise InputError(f"--out must end in .png, .svg, .pdf or .dot, got {out.name}")
    graph = _load_model_graph(args.model, np.array([50.0, 50.0, 20.0, 30.0]), None, args)
    out.parent.mkdir(parents=True, exist_ok=True)
    graph.draw(out)
    print(f"wrote {out}")
    return 0


def cmd_demo(args) -> int:
    from pgm.app.runner import track
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_single_gt
    from pgm.io.video import open_source
    from pgm.models import colour_pf, part_graph, single_object
    from pgm.synthetic import demo_scene

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seq = demo_scene(seed=args.seed, n_frames=args.frames)
    scene_dir = out / "scene"
    seq.write_otb(scene_dir, obj_index=0)
    gt = load_single_gt(scene_dir / "groundtruth_rect.txt")
    x, y, w, h = gt.boxes[0]
    box = (x + w / 2, y + h / 2, w, h)
    runs = [("colour PF (one node)", out,
             colour_pf.build_graph(colour_pf.Params(init_box=box,
                                                    num_particles=args.particles))),
            ("part graph (two nodes)", out / "part-graph",
             part_graph.build_graph(part_graph.Params(init_box=box, n_parts=2))),
            ("single-object (the default)", out / "single-object",
             single_object.build_graph(single_object.Params(init_box=box)))]
    results = []
    for label, folder, graph in runs:
        folder.mkdir(parents=True, exist_ok=True)
        graph.draw(folder / "graph.png")
        (folder / "graph.dot").write_text(graph.to_dot())
        results.append((label, track(open_source(scene_dir), graph, rng=as_generator(args.seed),
                                     out_dir=folder, gt=gt, show_particles=True,
                                     progress=not args.quiet)))
    print(f"demo: synthetic scene ({len(results[0][1].frames)} frames; the walker's lower half "
          f"passes behind a magazine) in {scene_dir}")
    print(f"demo: wrote tracks.txt, annotated.mp4, metrics.json, graph.png under {out} (colour "
          f"PF), {out / 'part-graph'} and {out / 'single-object'}")
    width = max(len(label) for label, _ in results)
    print(f"{'tracker':<{width}}  success AUC  precision@20px  frames/s")
    for label, r in results:
        m = r.metrics
        print(f"{label:<{width}}  {m['success_auc']:11.3f}  {m['precision_at_20']:14.3f}  "
              f"{r.fps:8.0f}")
    return 0


def cmd_learn(args) -> int:
    from pgm.core.rng import as_generator
    from pgm.observation.appearance.dbn import DBN, training_set
    from pgm.observation.appearance.features import PatchFeatures

    rng = as_generator(args.seed)
    feats = PatchFeatures()
    X, y = training_set(args.train, rng, every=args.every, features=feats)
    net = DBN()
    net.features_ = feats.to_dict()
    net.fit(X, y, rng, finetune_epochs=args.epochs)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    net.save(out)
    p = net.predict_proba(X)
    acc = float(np.mean((p > 0.5) == y))
    print(f"trained on {len(y)} patches ({int(y.sum())} people) from {len(args.train)} "
          f"sequence(s); training accuracy {acc:.3f}; wrote {out}")
    return 0


COMMANDS = {"track": cmd_track, "eval": cmd_eval, "graph": cmd_graph, "demo": cmd_demo,
            "learn": cmd_learn}


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pgm`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    debug = args.debug or os.environ.get("PGM_DEBUG") == "1"
    try:
        return COMMANDS[args.command](args)
    except KeyboardInterrupt:
        print("pgm: interrupted; results written so far are kept", file=sys.stderr)
        return 130
    except (InputError, ValueError, FileNotFoundError) as exc:
        if debug:
            raise
        msg = " ".join(str(exc).split())  # one line
        print(f"pgm: error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception as exc:  # noqa: BLE001 - last resort: one line, not a traceback
        if debug:
            raise
        msg = " ".join(str(exc).split())
        print(f"pgm: internal error: {type(exc).__name__}: {msg} (rerun with --debug for "
              f"the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
