"""``pgm track`` and the models' own options: the application asks a model's config.

The command line knows no model by name. ``pgm track --model NAME`` (or ``pgm graph
NAME``) finds the model's :class:`~pgm.models.config.ModelConfig` through the
``pgm.models`` entry points (:func:`pgm.models.get_config`), adds the options the config
declares to the parser (:func:`add_model_options`), and asks the config for the graph of
the video at hand (:meth:`~pgm.models.config.ModelConfig.graph_for`: its size, frame
rate, the initial box, the detections' typical height). What the model tracks — one
object from a box, many targets from detections — is its ``kind``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pgm.core.errors import InputError, one_line

from .cli_args import (
    _check_box_in_image,
    _given,
    _memory_limit,
    _print_metrics,
    _print_mot_metrics,
    _record_option,
    load_model_file,
    parse_box,
    parse_drop_frames,
    user_detector,
)

__all__ = ["cmd_track", "add_model_options", "model_values", "graph_from_config",
           "default_model", "GENERIC_MULTI_TARGET"]

#: options of ``pgm track`` that every multi-target model takes (measurements, gaps)
GENERIC_MULTI_TARGET = ("detections", "detector", "drop_frames")


def add_model_options(parser: argparse.ArgumentParser, config) -> None:
    """The options ``config`` declares, in their own group of ``parser``'s help."""
    if config is None or not config.options:
        return
    group = parser.add_argument_group(f"options of the model {config.name}",
                                      "(another model's: pgm track --model NAME --help)")
    for opt in config.options:
        group.add_argument(opt.flag, **opt.argparse_kwargs())
    parser.set_defaults(model_config=config)


def model_values(args: argparse.Namespace, config) -> dict:
    """The model's option values from ``args`` (``None`` where not given)."""
    return {o.dest: getattr(args, o.dest, None) for o in config.options}


def graph_from_config(config, args: argparse.Namespace, video):
    """``config.graph_for(values, video)``; a value the model refuses is an
    :class:`InputError` naming the options given (``--appearance 'cf(padding=1e6)':
    ...``), not only the factor or field that refused it."""
    values = model_values(args, config)
    try:
        return config.graph_for(values, video)
    except InputError:
        raise
    except (ValueError, TypeError) as exc:
        given = [f"{o.flag} {values[o.dest]!r}" for o in config.options
                 if values[o.dest] is not None and values[o.dest] is not False]
        msg = one_line(exc)
        if not given or any(o.flag in msg for o in config.options):
            raise InputError(f"model {config.name!r}: {msg}") from None
        raise InputError(f"{', '.join(given)}: {msg}") from None


def default_model(source: str | None, multi_target_hint: bool) -> str:
    """The model ``pgm track`` runs without ``--model``: the multi-target default when
    detections are given or the source has detections of its own (a MOTChallenge folder
    with ``det/det.txt``, or a video in one), else the single-object default."""
    return default_model_and_reason(source, multi_target_hint)[0]


def default_model_and_reason(source: str | None, multi_target_hint: bool) -> tuple[str, str]:
    """:func:`default_model` and why, in words (what ``pgm track`` prints)."""
    from pgm.models import DEFAULT_MULTI_TARGET, DEFAULT_SINGLE_OBJECT

    if multi_target_hint:
        return DEFAULT_MULTI_TARGET, "detections are given"
    det = source_detections(source)
    if det is not None:
        return DEFAULT_MULTI_TARGET, f"the source has detections: {det}"
    return DEFAULT_SINGLE_OBJECT, ("the source has no detections (det/det.txt); give "
                                   "--detections FILE or --detector NAME to track everyone")


def source_detections(source: str | None) -> Path | None:
    """The detections a source carries: ``det/det.txt`` of a folder, or beside a video in
    a MOTChallenge folder (a ``seqinfo.ini`` beside it, as :func:`pgm.io.video.open_source`
    reads it); None where it has none."""
    if source is None:
        return None
    try:
        p = Path(source)
        if p.is_dir():
            det = p / "det" / "det.txt"
        elif p.is_file() and (p.parent / "seqinfo.ini").is_file():
            det = p.parent / "det" / "det.txt"
        else:
            return None
        return det if det.is_file() else None
    except (OSError, ValueError):
        return None


def _say_saved_rates(graph, fps: float | None, args) -> None:
    """A saved model's factors discretised at a frame rate of their own (the motion
    library's) keep it: where the video's differs, said (rebuilding the model at the
    video's rate is the user's call)."""
    from pgm.factors.motion import MotionTransition

    rates = sorted({float(f.fps) for f in graph.factors.values()
                    if isinstance(f, MotionTransition)})
    if fps is None or not rates or rates == [float(fps)] or args.quiet:
        return
    print(f"pgm: using the saved model's motion as discretised at "
          f"{', '.join(f'{r:g}' for r in rates)} frames/s (the video's is {fps:g}: a saved "
          f"model is not re-discretised; rebuild it with fps={fps:g})", file=sys.stderr)


def _with_init_box(graph, box_cxcywh: np.ndarray, path: str):
    """A saved single-object graph moved to start on ``box_cxcywh``: every prior over a
    ``(cx, cy, w, h)`` box is re-centred as the target's box moves and scales from the
    saved one (``meta["reference_box"]``, else the bounding box of the output variables'
    prior means), so the parts of a part graph keep their places on the target; the
    covariances and everything else are kept. Unchanged where the box is the saved one."""
    from pgm.core.boxes import bounding_box, box_coding, place_parts
    from pgm.core.graph import FactorGraph

    priors = [f for f in graph.factors.values() if f.kind == "prior"]
    movable = [f for f in priors if hasattr(f, "born_at") and hasattr(f, "mean")
               and box_coding(graph.variables[f.variables[0]].labels) == "cxcywh"]
    if not priors or len(movable) != len(priors):
        raise InputError(f"cannot move saved model {path} to a new initial box: its priors "
                         f"are not all Gaussian priors over (cx, cy, w, h); leave out "
                         f"--init/--gt to start where it was saved, or build it with "
                         f"--model NAME")
    means = {f.variables[0]: np.asarray(f.mean(), dtype=float).reshape(-1)[:4]
             for f in movable}
    ref = graph.meta.get("reference_box")
    outputs = [v for v in graph.output if v in means] or list(means)
    ref = (np.asarray(ref, dtype=float) if ref is not None
           else bounding_box([means[v] for v in outputs]))
    box = np.asarray(box_cxcywh, dtype=float)
    if np.array_equal(box, ref):
        return graph
    values = place_parts(box, ref, means)
    moved = {f.name: f.born_at(values[f.variables[0]], graph.variables[f.variables[0]].labels)
             for f in movable}
    factors = [moved.get(f.name, f) for f in graph.factors.values()]
    meta = dict(graph.meta)
    if "reference_box" in meta:
        meta["reference_box"] = box.tolist()
    return FactorGraph(list(graph.variables.values()), factors, name=graph.name, meta=meta,
                       plates=graph.plates)


def _kind(args: argparse.Namespace, saved) -> str:
    """What the run tracks: a saved graph's by its variables (a set or a plate: many
    targets), a named model's by its config."""
    if saved is not None:
        return "multi-target" if saved.multi_target else "single-object"
    return args.model_config.kind


def cmd_track_multi(args, source, saved=None) -> int:
    """``pgm track`` with a multi-target model: detections, the graph, :func:`track_multi`."""
    from pgm.app.runner import track_multi
    from pgm.io.annotations import load_mot
    from pgm.models.config import VideoInfo
    from pgm.observation.detections import PublicDetections, make_detector, names_a_function

    if args.init is not None:
        raise InputError(f"--init does not apply to the multi-target model {args.model!r}")
    if args.detections is not None and args.detector is not None:
        raise InputError("give either --detections FILE or --detector SPEC, not both")
    if args.detections is not None:
        detector = PublicDetections(args.detections)
    elif names_a_function(args.detector):
        detector = user_detector(args.detector)
    else:
        detector = make_detector(args.detector or "public", source)
    gt_path = args.gt or source.gt_path
    gt = load_mot(gt_path, kind="gt") if gt_path is not None else None
    engine_kwargs = None
    if saved is not None:
        graph = saved
        if args.particles is not None:
            engine_kwargs = {"num_particles": args.particles}
    else:
        width, height = source.size
        table = getattr(detector, "table", None)  # public detections: their median height
        typical = float(np.median(table.boxes[:, 3])) if table is not None and len(table) \
            else None
        video = VideoInfo(width=width, height=height, fps=float(source.fps),
                          fps_declared=source.fps_declared,
                          typical_height=typical, particles=args.particles,
                          score_range=getattr(detector, "score_range", None))
        graph = graph_from_config(args.model_config, args, video)
    result = track_multi(source, graph, detector, rng=args.seed, out_dir=args.out,
                         gt=gt, write_video=not args.no_video, show_particles=args.show_particles,
                         progress=not args.quiet, max_frames=args.max_frames,
                         camera_motion=args.camera_motion or "auto",
                         engine_kwargs=engine_kwargs,
                         memory_limit_bytes=_memory_limit(args),
                         drop_frames=parse_drop_frames(args.drop_frames, len(source)),
                         command=getattr(args, "argv", None), video_scale=args.video_scale,
                         trails=args.trails,
                         record=_record_option(args))
    print(f"tracked {result.n_frames} frames: {result.end_to_end_fps:.1f} frames/s end to end, "
          f"{result.fps:.1f} inference (camera motion included), "
          f"{result.n_frames / max(result.detector_seconds, 1e-9):.0f} detector alone -> "
          f"{Path(args.out) / 'tracks.txt'}")
    if result.metrics is not None:
        _print_mot_metrics(result.metrics)
    return 0


def _single_gt(gt_path, args):
    """The single object's ground truth: of a MOTChallenge file of several people, the
    identity ``--gt-id`` names; without one, a refusal naming the choices (no ``--init``)
    or no ground truth at all (``--init``: which person it follows is not known)."""
    from pgm.io.annotations import detect_gt_format, load_mot, load_single_gt

    if detect_gt_format(gt_path) != "mot":
        if args.gt_id is not None:
            raise InputError(f"--gt-id applies to a MOTChallenge ground truth of several "
                             f"people; {gt_path} is a single object's")
        return load_single_gt(gt_path)
    table = load_mot(gt_path, kind="gt")
    ids = np.unique(table.ids[~table.ignore]) if len(table) else np.zeros(0, np.int64)

    def listed(values, most: int = 8) -> str:
        return (", ".join(map(str, values[:most])) + (", ..." if values.size > most else "")
                or "none")

    first = np.unique(table.ids[(table.frames == 1) & ~table.ignore])
    if args.gt_id is not None:
        if args.gt_id not in ids:
            raise InputError(f"--gt-id {args.gt_id}: no such identity in {gt_path} "
                             f"(identities: {listed(ids, 12)})")
        track = load_single_gt(gt_path, "mot", obj_id=int(args.gt_id))
        if args.init is None and int(track.frames[0]) > 1:
            raise InputError(f"--gt-id {args.gt_id} is first annotated in frame "
                             f"{int(track.frames[0])} of {gt_path}, and the run starts at "
                             f"frame 1: give --init X,Y,W,H, or an identity annotated in "
                             f"frame 1 ({listed(first)})")
        return track
    if ids.size <= 1:
        return load_single_gt(gt_path, "mot")
    if args.init is None:
        # a file not named gt.txt is read as MOTChallenge rows by its column count: said
        read_as = ("" if Path(gt_path).name.lower() == "gt.txt" else
                   " (read as MOTChallenge rows frame,id,x,y,w,h,... for its 6 or more columns)")
        raise InputError(f"{gt_path}{read_as} holds {ids.size} people and model {args.model!r} "
                         f"follows one: give --gt-id ID (annotated in frame 1: "
                         f"{listed(first)}) or --init X,Y,W,H, or track everyone with "
                         f"--detections FILE or --detector NAME")
    if not args.quiet:
        print(f"pgm: {gt_path} holds {ids.size} people; the run is not scored (give --gt-id "
              f"ID to score the person --init starts on)", file=sys.stderr)
    return None


def cmd_track(args) -> int:
    """``pgm track``: one object from a box, or every target from detections, as the
    model's kind says."""
    from pgm.app.runner import init_box_from_gt, track
    from pgm.io.video import open_source
    from pgm.models.config import VideoInfo

    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise InputError(f"--out {args.out} exists and is not a folder")
    source = open_source(args.source)
    if args.fps is not None:
        source.declare_fps(args.fps)
    elif not source.fps_declared and not args.quiet:
        print(f"pgm: using the model's reference frame rate ({args.source} does not say its "
              f"own: give --fps F where it differs, docs/usage.md)", file=sys.stderr)
    saved = None
    if args.model is None:
        args.model = args.model_config.name
        if not args.quiet:
            hint = _given(args, "detections") or _given(args, "detector")
            _, why = default_model_and_reason(args.source, hint)
            print(f"pgm: using model {args.model} (no --model given; {why})", file=sys.stderr)
    if args.model.endswith(".json"):
        saved = load_model_file(args.model)
        _say_saved_rates(saved, source.fps if source.fps_declared else None, args)
    kind = _kind(args, saved)
    if kind == "state-space":
        raise InputError(f"model {args.model!r} is a state-space model without an image "
                         f"likelihood: it runs on measurements from Python "
                         f"(pgm.inference.Engine), not on a video")
    if kind == "multi-target":
        if args.gt_id is not None:
            raise InputError(f"--gt-id picks the one person a single-object model follows; "
                             f"{args.model!r} tracks every target (leave --gt-id out)")
        return cmd_track_multi(args, source, saved)
    if _given(args, "detections") or _given(args, "detector"):
        raise InputError(f"--detections/--detector apply to multi-target models, not to the "
                         f"single-object model {args.model!r}")
    if _given(args, "drop_frames"):
        raise InputError(f"--drop-frames applies to plate models (one sub-graph per "
                         f"target), not to the single-object model {args.model!r}")
    gt = None
    gt_path = args.gt
    own_gt = gt_path is None and args.init is None and source.gt_path is not None
    if own_gt:
        gt_path = str(source.gt_path)
        if not args.quiet:
            print(f"pgm: using the sequence's ground truth {gt_path}", file=sys.stderr)
    elif gt_path is None and source.gt_path is not None and not args.quiet:
        # the --init box may be another object than the one annotated: said, not guessed
        print(f"pgm: using no ground truth (--init gives the object, which the sequence's "
              f"own {source.gt_path} may not annotate: add --gt to score against it)",
              file=sys.stderr)
    if gt_path is not None:
        gt = _single_gt(gt_path, args)
    box_xywh, what = None, "--init box"
    if args.init is not None:
        box_xywh = parse_box(args.init)
    elif gt is not None:
        c = init_box_from_gt(gt, 1)
        box_xywh = np.array([c[0] - c[2] / 2, c[1] - c[3] / 2, c[2], c[3]])
        what = f"the first box of {gt_path}"
    elif saved is None:
        raise InputError("give the initial box with --init X,Y,W,H or a ground truth with --gt")
    init_c = None
    if box_xywh is not None:
        _check_box_in_image(box_xywh, source.size, what)
        init_c = np.array([box_xywh[0] + box_xywh[2] / 2, box_xywh[1] + box_xywh[3] / 2,
                           box_xywh[2], box_xywh[3]])
    if saved is not None:
        try:
            graph = saved if init_c is None else _with_init_box(saved, init_c, args.model)
        except InputError:
            if not own_gt:  # a box the user gave: the refusal says how to go on
                raise
            graph = saved  # the sequence's own ground truth asked nothing: start as saved
            if not args.quiet:
                print(f"pgm: using the saved model's own start (its priors are not all "
                      f"Gaussian priors over (cx, cy, w, h): it is not moved to the first box "
                      f"of {gt_path})", file=sys.stderr)
    else:
        width, height = source.size
        graph = graph_from_config(args.model_config, args, VideoInfo(
            width=width, height=height, fps=float(source.fps), particles=args.particles,
            init_box=tuple(float(v) for v in init_c), fps_declared=source.fps_declared))
    result = track(source, graph, rng=args.seed, out_dir=args.out, gt=gt,
                   num_particles=args.particles, write_video=not args.no_video,
                   show_particles=args.show_particles, progress=not args.quiet,
                   max_frames=args.max_frames, camera_motion=args.camera_motion or "off",
                   memory_limit_bytes=_memory_limit(args), record=_record_option(args),
                   lost_below=args.lost_below, command=getattr(args, "argv", None),
                   video_scale=args.video_scale, trails=args.trails)
    print(f"tracked {len(result.frames)} frames: {result.end_to_end_fps:.1f} frames/s end to "
          f"end, {result.fps:.1f} inference (camera motion included) -> "
          f"{Path(args.out) / 'tracks.txt'}")
    if result.metrics is not None:
        _print_metrics({**result.metrics, "fps": result.fps})
    return 0
