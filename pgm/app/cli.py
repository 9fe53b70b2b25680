"""The ``pgm`` command line.

::

    pgm track SOURCE [--model single-object|colour-pf|part-graph] (--init X,Y,W,H | --gt FILE)
              --out DIR
              [--parts 2|3] [--fusion mixture|product] [--particles N] [--seed S]
              [--no-video] [--show-particles]
    pgm track SOURCE --model phd|vb-phd [--detections FILE | --detector public|mog2]
              --out DIR [--gt FILE]
    pgm track SOURCE --model multi-pf [--parts 2|3] [--appearance CUES] --out DIR
    pgm track SOURCE --model gpdm --gpdm FILE.npz [--motion gpdm|cv|cv3]
              [--drop-frames A-B,...|P/L] --out DIR
    pgm eval --gt FILE --pred DIR/tracks.txt [--json]
    pgm eval --gt-dir GT --pred-dir PRED [--json]
    pgm graph MODEL [--parts 2|3] --out FILE.{png,svg,pdf,dot}
    pgm learn dbn --train SEQ [SEQ ...] --out FILE.npz
    pgm learn gpdm --train SEQ [SEQ ...] --out FILE.npz [--plot FILE.png]
    pgm demo --out DIR

Bad input (a missing or corrupt video, a malformed box or ground-truth file, a bad
parameter, a path the file system refuses, a run larger than the memory cap) gets a
one-line ``pgm: error: ...`` and exit code 2, never a traceback: :func:`main` is the one
place that maps failures to messages (through :func:`pgm.core.errors.user_message`).
SIGINT and SIGTERM stop a run the same way (rows kept, video finalised, ``run.json``
says ``"complete": false``; exit 130 or 143). Warnings are one line each,
``pgm: warning: ...`` (the ``logging`` logger ``pgm``); FFmpeg's and OpenCV's own log
lines are silenced.
The CLI sits on top of everything and may import :mod:`pgm.models`: imports otherwise go
one way, ``models → inference → pgm``, and a test of the code base enforces it.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import signal
import sys
import warnings
from pathlib import Path

import numpy as np

from pgm.core.errors import InputError, Interrupted, one_line, user_message

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


def _int_in(name: str, low: int, high: int):
    """An argparse type: an integer in ``[low, high]``."""
    at_least = _int_at_least(name, low)

    def conv(text: str) -> int:
        v = at_least(text)
        if v > high:
            raise argparse.ArgumentTypeError(f"{name} must be between {low} and {high}, "
                                             f"got {v}")
        return v

    return conv


def _finite_float(name: str, low: float = 0.0):
    """An argparse type: a finite number ``>= low``."""
    def conv(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") \
                from None
        if not np.isfinite(v) or v < low:
            raise argparse.ArgumentTypeError(f"{name} must be a finite number >= {low:g}, "
                                             f"got {text!r}")
        return v

    return conv


_nonneg_int = _int_at_least("seed", 0)


def _path(name: str):
    """An argparse type: a path, which may not be empty (``--out ''`` would write into
    the current folder) or all white space."""
    def conv(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{name} is empty: give a path")
        return text

    return conv


#: options whose value is a comma-separated list of numbers that may start with "-"
NUMBER_LIST_OPTIONS = ("--init",)
_NUMBER_LIST = re.compile(r"-[0-9.][0-9.eE+-]*(,[^,]*)*")


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Every ``--help`` of ``pgm``: each option's default is shown.

    An option whose help already says its default (``(default: ...)``, or a word such as
    "default" in the text) is left as written; an option with a value of its own gets
    ``(default: VALUE)``; a flag (no value) is off unless given and says nothing. A
    description or epilog with line breaks is printed as written (examples), a one-line
    one is wrapped.
    """

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("default" in text.lower() or action.nargs == 0 or action.default is None
                or action.default is argparse.SUPPRESS or not action.option_strings):
            return text
        return f"{text} (default: %(default)s)" if text else "default: %(default)s"

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if "\n" in text:
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``pgm: error: ...``), exit 2, and
    whose help shows every default (:class:`HelpFormatter`)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def parse_known_args(self, args=None, namespace=None):
        # argparse takes "-3,10,20,20" for an option, not for --init's value (it knows
        # only "-3" and "-.5" as negative numbers): join such a value to its option
        args = list(sys.argv[1:] if args is None else args)
        for i in range(len(args) - 1, 0, -1):
            if args[i - 1] in NUMBER_LIST_OPTIONS and _NUMBER_LIST.fullmatch(args[i]):
                args[i - 1:i + 1] = [f"{args[i - 1]}={args[i]}"]
        return super().parse_known_args(args, namespace)

    def error(self, message: str):
        self.exit(EXIT_BAD_INPUT, f"pgm: error: {' '.join(message.split())} "
                                  f"(see {self.prog} --help)\n")


#: the names of :data:`pgm.models.MODELS`, for the help: building the parser imports no
#: model (nor the inference engine), so ``pgm eval``, ``report``, ``view`` and ``--help``
#: start fast (a test keeps the two equal)
MODEL_NAMES = ("colour-pf", "gpdm", "multi-pf", "part-graph", "phd", "single-object",
               "vb-phd")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``pgm``."""
    p = _Parser(
        prog="pgm", description="Visual trackers declared as factor graphs, run by one engine.")
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    from pgm import __version__

    p.add_argument("--version", action="version", version=f"pgm {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    t = sub.add_parser("track", help="track an object through a video or image sequence")
    t.add_argument("source", type=_path("SOURCE"),
                   help="a video file, an image folder, a MOTChallenge, OTB or MILTrack "
                        "sequence folder, a camera index (0, 1, ...) or a stream URL "
                        "(rtsp://, rtmp://, http(s)://, udp://, tcp://)")
    t.add_argument("--model", default=None,
                   help=f"model name ({', '.join(MODEL_NAMES)}) or a saved model .json; "
                        f"default: single-object (the correlation-filter tracker), or "
                        f"vb-phd when --detections/--detector is given")
    init = t.add_mutually_exclusive_group()
    init.add_argument("--init", metavar="X,Y,W,H",
                      help="box in frame 1: top-left corner and size, 1-based like MOT/OTB; "
                           "may start left of or above the image, e.g. --init -3,10,20,20 "
                           "(default: frame 1 of --gt, else of the sequence's own ground "
                           "truth)")
    t.add_argument("--gt", type=_path("--gt"), metavar="FILE",
                   help="ground-truth file: initialises from frame 1 when --init is absent "
                        "and writes metrics.json (default: the sequence's own, if any)")
    t.add_argument("--out", type=_path("--out"), required=True, help="output folder")
    t.add_argument("--particles", type=_positive_int("--particles"), default=None,
                   help="particles per variable (default: the model's)")
    _model_options(t)
    t.add_argument("--seed", type=_nonneg_int, default=0, metavar="S",
                   help="seed of the run's random numbers; the same seed gives the same "
                        "results")
    t.add_argument("--no-video", action="store_true", help="do not write annotated.mp4")
    t.add_argument("--show-particles", action="store_true",
                   help="draw particles in the annotated video")
    t.add_argument("--max-frames", type=_positive_int("--max-frames"), default=None,
                   metavar="K", help="track the first K frames only (default: every frame)")
    t.add_argument("--camera-motion", choices=("auto", "on", "off"), default=None,
                   help="global-motion compensation of every target's prediction: auto (on "
                        "frames where the camera moves; the default for multi-target "
                        "models), on, off (the default for one object, whose camera "
                        "usually follows it)")
    t.add_argument("--detections", type=_path("--detections"), metavar="FILE",
                   help="multi-target models: a MOTChallenge det.txt to use as measurements "
                        "(default: none; see --detector)")
    t.add_argument("--gpdm", type=_path("--gpdm"), default=None, metavar="FILE.npz",
                   help="gpdm: the learned dynamics ('pgm learn gpdm'); needed by --motion "
                        "gpdm (default: none)")
    t.add_argument("--motion", choices=("gpdm", "cv", "cv3"), default=None,
                   help="gpdm: the motion model: the learned GPDM (default), constant "
                        "velocity, or constant velocity averaged over three frames")
    t.add_argument("--drop-frames", default=None, metavar="SPEC",
                   help="multi-pf/gpdm: withhold frames to simulate missing ones (predicted "
                        "through, still scored): ranges 'A-B,C-D' (1-based, inclusive) or "
                        "'P/L' (the last L of every P frames), e.g. '50-59' or '30/10' "
                        "(default: none)")
    t.add_argument("--dbn", type=_path("--dbn"), metavar="FILE.npz",
                   help="phd/vb-phd: a DBN person likelihood trained by 'pgm learn dbn' "
                        "(multiplies the detection terms; default: none)")
    t.add_argument("--scale-aware", action="store_true",
                   help="phd/vb-phd: track each box's scale; noise in units of each target's "
                        "own height (experimental: see the README's MOT table)")
    t.add_argument("--per-track-noise", action="store_true",
                   help="vb-phd: one noise belief per track instead of one shared")
    t.add_argument("--scores", choices=("off", "mixture"), default=None,
                   help="phd/vb-phd: detection scores in the measurement model: 'mixture' "
                        "(default: a two-class score mixture fitted on the video's own "
                        "scores; confident detections start targets, a tracked target's "
                        "low-score detections still update it) or 'off' (score-blind)")
    t.add_argument("--detector", default=None,
                   help="phd/vb-phd: 'public' (the sequence's det/det.txt, default), "
                        "'public:MIN_SCORE' or 'mog2' (background subtraction)")
    t.add_argument("--quiet", action="store_true", help="no progress bar")
    t.add_argument("--memory-limit", default=None, metavar="SIZE",
                   help="refuse a run whose estimated memory exceeds SIZE (e.g. 8G); "
                        "default: PGM_MEMORY_LIMIT, else 80%% of the physical memory")
    _record_options(t)

    e = sub.add_parser(
        "eval", help="score a tracks.txt (or a folder of results) against ground truth",
        description="Score one result file against its ground truth (--gt FILE --pred FILE:\n"
                    "single object (OTB) or MOT metrics), or every sequence of a folder\n"
                    "(--gt-dir DIR --pred-dir DIR, MOTChallenge layout: GT/<SEQ>/gt/gt.txt\n"
                    "or GT/<SEQ>.txt against PRED/<SEQ>.txt). With folders, a ground-truth\n"
                    "sequence without a prediction file is scored as an empty prediction\n"
                    "and listed; COMBINED scores all sequences as one (counts summed,\n"
                    "MOTA/IDF1/HOTA of the pooled counts, OSPA over all frames) and MEAN is\n"
                    "the unweighted mean over sequences.",
        epilog="examples:\n  pgm eval --gt ../shared/data/TUD-Campus/gt/gt.txt --pred "
               "out/tracks.txt\n  pgm eval --gt-dir ../shared/data --pred-dir results/ "
               "--json")
    e.add_argument("--gt", type=_path("--gt"), metavar="FILE",
                   help="ground truth (OTB, MILTrack or MOT gt.txt); with --pred (default: "
                        "none: give --gt/--pred or --gt-dir/--pred-dir)")
    e.add_argument("--pred", type=_path("--pred"), metavar="FILE",
                   help="tracks.txt written by pgm track; with --gt (default: none)")
    e.add_argument("--gt-dir", type=_path("--gt-dir"), default=None, metavar="DIR",
                   help="folder of ground truth: <SEQ>/gt/gt.txt folders or <SEQ>.txt files "
                        "(MOT); with --pred-dir (default: none)")
    e.add_argument("--pred-dir", type=_path("--pred-dir"), default=None, metavar="DIR",
                   help="folder of results <SEQ>.txt (MOTChallenge rows); with --gt-dir "
                        "(default: none)")
    e.add_argument("--json", action="store_true", help="print JSON instead of a table")

    g = sub.add_parser("graph", help="draw a model's factor graph")
    g.add_argument("model", help=f"model name ({', '.join(MODEL_NAMES)}) or a model .json")
    g.add_argument("--out", type=_path("--out"), required=True, help="FILE.png, .svg, .pdf or .dot")
    _model_options(g)

    lp = sub.add_parser("learn", help="learn model parameters from annotated sequences")
    lsub = lp.add_subparsers(dest="what", required=True, parser_class=_Parser)
    ld = lsub.add_parser("dbn", help="train the deep-belief-network person likelihood")
    ld.add_argument("--train", type=_path("--train"), nargs="+", required=True,
                    help="MOTChallenge sequence folders with gt/gt.txt (never the one you "
                         "will evaluate on)")
    ld.add_argument("--out", type=_path("--out"), required=True, help="output .npz file")
    ld.add_argument("--every", type=_positive_int("--every"), default=3,
                    help="use every K-th annotated frame")
    ld.add_argument("--seed", type=_nonneg_int, default=0, metavar="S",
                    help="seed of the patch sampling and the network's initial weights")
    ld.add_argument("--epochs", type=_positive_int("--epochs"), default=40,
                    help="fine-tuning epochs")
    _learn_gpdm_options(lsub)

    d = sub.add_parser("demo", help="render a synthetic scene, track it, write every output")
    d.add_argument("--out", type=_path("--out"), required=True, help="output folder")
    d.add_argument("--seed", type=_nonneg_int, default=0, metavar="S",
                   help="seed of the synthetic scene and of the trackers")
    d.add_argument("--frames", type=_positive_int("--frames"), default=90, metavar="K",
                   help="length of the synthetic scene")
    d.add_argument("--particles", type=_positive_int("--particles"), default=100,
                   metavar="N", help="particles of the colour particle filter")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    for module in _extensions():
        module.add_parser(sub)
    return p


#: modules adding sub-commands: each has ``add_parser(subparsers)`` and ``COMMANDS``
#: (name → ``cmd(args) -> int``), and imports nothing heavy at module level
EXTENSIONS: tuple[str, ...] = ("pgm.app.view", "pgm.app.experiment", "pgm.app.report")


def _extensions():
    import importlib

    return [importlib.import_module(m) for m in EXTENSIONS]


#: defaults of ``pgm learn gpdm`` shown in its help; the values used are
#: :class:`pgm.dynamics.gpdm.GPDMSettings`'s (read when the command runs, so that building
#: the parser does not import torch; a test keeps the two equal)
GPDM_HELP_DEFAULTS = {"latent_dim": 2, "mirror": False, "max_iter": 200}


def _learn_gpdm_options(lsub) -> None:
    """The ``pgm learn gpdm`` sub-parser."""
    d = GPDM_HELP_DEFAULTS
    lg = lsub.add_parser(
        "gpdm", help="learn a Gaussian-process dynamical model of people's motion",
        description="Learn a GPDM (SPEC section 4) from the ground-truth trajectories of\n"
                    "MOTChallenge sequences: each person's box changes (dcx, dtop, dh) in\n"
                    "box heights per second at the sequence's frame rate (seqinfo.ini),\n"
                    "one GP over all of them. The .npz model is for\n"
                    "'pgm track SOURCE --model gpdm --gpdm FILE.npz'.",
        epilog="example:\n  pgm learn gpdm --train ../shared/data/TUD-Stadtmitte "
               "../shared/data/TUD-Campus \\\n      --out gpdm_tud.npz --plot gpdm_tud.png "
               "--mirror")
    lg.add_argument("--train", type=_path("--train"), nargs="+", required=True, metavar="SEQ",
                    help="MOTChallenge sequence folders with gt/gt.txt and seqinfo.ini "
                         "(frameRate); never the one you will evaluate on")
    lg.add_argument("--out", type=_path("--out"), required=True, metavar="FILE.npz",
                    help="output model file")
    lg.add_argument("--plot", type=_path("--plot"), default=None, metavar="FILE.png",
                    help="also draw the latent space (.png, .svg or .pdf; default: none)")
    lg.add_argument("--latent-dim", type=_positive_int("--latent-dim"), default=None,
                    metavar="D",
                    help=f"latent dimension d (default: {d['latent_dim']})")
    lg.add_argument("--seed", type=_nonneg_int, default=0, metavar="S",
                    help="seed of the subsampling of long training sets (default: "
                         "%(default)s)")
    lg.add_argument("--mirror", action=argparse.BooleanOptionalAction, default=None,
                    help="add every trajectory mirrored left-right, removing the scenes' "
                         f"mean horizontal flow (default: {'on' if d['mirror'] else 'off'})")
    lg.add_argument("--balanced", action="store_true",
                    help="balanced GPDM: the dynamics term weighted by D/d (default: off)")
    lg.add_argument("--max-iter", type=_int_at_least("--max-iter", 0), default=None,
                    metavar="N",
                    help=f"cap on L-BFGS iterations (default: {d['max_iter']})")


def _record_options(t: argparse.ArgumentParser) -> None:
    """``pgm track``'s ``--record*`` options (the record ``pgm view`` shows)."""
    t.add_argument("--record", action="store_true",
                   help="keep what 'pgm view DIR' shows in DIR/record: subsampled particles, "
                        "messages, PHD intensity, VB iterations, ESS (off by default)")
    t.add_argument("--record-particles", type=_positive_int("--record-particles"),
                   default=None, metavar="K",
                   help="record: particles kept per variable and message each frame "
                        "(default: 200; implies --record)")
    t.add_argument("--record-frames", type=_positive_int("--record-frames"), default=None,
                   metavar="M", help="record: frames kept at most (default: 300, the first "
                                     "ones; implies --record)")
    t.add_argument("--record-every", type=_positive_int("--record-every"), default=None,
                   metavar="K", help="record: every K-th frame (default: 1; implies --record)")


def _record_option(args: argparse.Namespace):
    """The ``record=`` argument of the runners from ``--record*`` (``None``: off)."""
    from pgm.app.record import RecordSettings

    given = {k: getattr(args, f"record_{k}", None) for k in ("particles", "frames", "every")}
    given = {k: v for k, v in given.items() if v is not None}
    if not getattr(args, "record", False) and not given:
        return None
    return RecordSettings(**given)


def _model_options(p: argparse.ArgumentParser) -> None:
    """Options that set a model config's ``Params`` fields (used where the model has them)."""
    p.add_argument("--parts", type=_int_in("--parts", 1, 3), default=None,
                   help="part-graph, multi-pf: number of bands (2 for a person, 3 for a "
                        "face; default: the model's)")
    p.add_argument("--split", choices=("rows", "cols"), default=None,
                   help="part-graph: horizontal (rows) or vertical bands (default: the "
                        "model's, rows)")
    p.add_argument("--topology", choices=("chain", "full"), default=None,
                   help="part-graph: couplings between neighbours (chain) or all pairs "
                        "(default: the model's, chain)")
    p.add_argument("--fusion", choices=("mixture", "product"), default=None,
                   help="part-graph: particle-BP fusion rule (default: the model's, "
                        "mixture)")
    p.add_argument("--appearance", default=None, metavar="CUE[+CUE...]",
                   help="single-object/colour-pf/part-graph: likelihood cues per node, "
                        "multiplied: colour (one colour histogram), fragments (3x3 colour "
                        "fragments, median), gradient (oriented gradients), gmm (GMM-KL), "
                        "rings (rotation-invariant), contrast (foreground/background colour "
                        "log-odds), template (grey NCC; sees scale), cf (online correlation "
                        "filter; the default's cue); options in parentheses, e.g. "
                        "'cf(lam=40,padding=2)+template' (default: the model's: cf for "
                        "single-object, colour for the others)")
    p.add_argument("--scale-noise", type=_finite_float("--scale-noise"), default=None,
                   help="single-object/colour-pf/part-graph: std of a shared log-scale step "
                        "per frame (0: fixed size; use with a cue that sees scale; "
                        "default: the model's)")


# -- commands ---------------------------------------------------------------------------
MODEL_OPTIONS = {"parts": "n_parts", "split": "split", "topology": "topology",
                 "fusion": "fusion", "appearance": "appearance", "scale_noise": "scale_noise"}
MULTI_TARGET_OPTIONS = ("dbn", "per_track_noise", "scale_aware", "scores", "gpdm", "motion",
                        "drop_frames")


def _flag(opt: str) -> str:
    return "--" + opt.replace("_", "-")


def _given(args: argparse.Namespace | None, opt: str) -> bool:
    value = getattr(args, opt, None) if args is not None else None
    return value is not None and value is not False


def load_model_file(path: str | Path):
    """A saved ``model.json`` as a :class:`~pgm.core.graph.FactorGraph` (plain JSON, no
    code runs); every malformation is an :class:`InputError` naming the file."""
    from pgm.core.graph import FactorGraph

    p = Path(path)
    if p.is_dir():
        raise InputError(f"model file {p} is a folder")
    try:
        return FactorGraph.load(p)
    except InputError:
        raise
    except ValueError as exc:
        msg = one_line(exc)
        raise InputError(msg if str(p) in msg else f"model file {p}: {msg}") from None
    except (KeyError, TypeError, AttributeError, IndexError, RecursionError,
            OverflowError) as exc:
        raise InputError(f"model file {p} is malformed: {type(exc).__name__}: "
                         f"{one_line(exc)[:120]}") from None


def _is_multi_target(graph) -> bool:
    return bool(graph.plates) or any(v.role == "set" for v in graph.variables.values())


def _reject_model_options(args: argparse.Namespace | None, what: str) -> None:
    for opt in MODEL_OPTIONS:
        if _given(args, opt):
            raise InputError(f"{_flag(opt)} does not apply to {what}")


def _load_model_graph(model: str, init_box_cxcywh: np.ndarray | None,
                      num_particles: int | None, args: argparse.Namespace | None = None):
    """The graph of a model name (``Params`` from the options) or of a saved ``.json``."""
    import dataclasses

    from pgm.models import get_model

    if model.endswith(".json"):
        graph = load_model_file(model)
        _reject_model_options(args, f"a saved model ({model}): its factors are fixed; "
                                    f"build one with --model NAME and the option instead")
        return graph
    module = get_model(model)
    fields = {f.name for f in dataclasses.fields(module.Params)}
    kwargs = {}
    if "init_box" in fields and init_box_cxcywh is not None:
        kwargs["init_box"] = tuple(float(v) for v in init_box_cxcywh)
    if num_particles is not None and "num_particles" in fields:
        kwargs["num_particles"] = num_particles
    for opt, field in MODEL_OPTIONS.items():
        if not _given(args, opt):
            continue
        if field not in fields:
            raise InputError(f"{_flag(opt)} does not apply to model {model!r}")
        kwargs[field] = getattr(args, opt)
    return _build(module, kwargs, args)


def _build(module, kwargs: dict, args: argparse.Namespace | None):
    """``module.build_graph(module.Params(**kwargs))``; a value the model refuses is an
    :class:`InputError` that names the options given (``--appearance 'cf(padding=1e6)':
    ...``), not only the factor or field that refused it."""
    try:
        return module.build_graph(module.Params(**kwargs))
    except InputError:
        raise
    except ValueError as exc:
        given = [f"{_flag(opt)} {getattr(args, opt)!r}" for opt in MODEL_OPTIONS
                 if _given(args, opt)]
        if not given:
            raise
        raise InputError(f"{', '.join(given)}: {one_line(exc)}") from None


def _with_init_box(graph, box_cxcywh: np.ndarray, path: str):
    """A saved single-object graph moved to start on ``box_cxcywh``: its one Gaussian
    prior over ``(cx, cy, w, h)`` gets the box as its mean (everything else is kept)."""
    from pgm.core.graph import FactorGraph
    from pgm.factors.gaussian import GaussianPrior

    priors = [f for f in graph.factors.values() if f.kind == "prior"]
    ok = (len(priors) == 1 and isinstance(priors[0], GaussianPrior)
          and priors[0].mean_.size == 4)
    if not ok:
        raise InputError(f"cannot move saved model {path} to a new initial box: it has "
                         f"{len(priors)} priors (one over cx, cy, w, h is needed); leave out "
                         f"--init/--gt to start where it was saved, or build it with "
                         f"--model NAME")
    old = priors[0]
    new = GaussianPrior(old.variables[0], mean=np.asarray(box_cxcywh, dtype=float),
                        cov=old.cov, name=old.name)
    factors = [new if f is old else f for f in graph.factors.values()]
    return FactorGraph(list(graph.variables.values()), factors, name=graph.name,
                       meta=graph.meta)


#: how many times the image's width (height) an initial box may be wide (high)
MAX_BOX_SCALE = 4.0


def _check_box_in_image(box_xywh: np.ndarray, size: tuple[int, int],
                        what: str = "initial box") -> None:
    """The initial box must overlap the image and be at most :data:`MAX_BOX_SCALE` times
    its size (``--init 1,1,1e308,1e308`` is refused here, naming ``what``, not deep in a
    model as a non-finite noise parameter)."""
    w_img, h_img = size
    x, y, w, h = box_xywh
    text = f"{what} ({x + 1:g},{y + 1:g},{w:g},{h:g})"
    if x >= w_img or y >= h_img or x + w <= 0 or y + h <= 0:
        raise InputError(f"{text} lies outside the {w_img}x{h_img} image")
    if w > MAX_BOX_SCALE * w_img or h > MAX_BOX_SCALE * h_img:
        raise InputError(f"{text} is more than {MAX_BOX_SCALE:g} times the {w_img}x{h_img} "
                         f"image")


def _fmt(value, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def _print_metrics(metrics: dict, stream=None) -> None:
    stream = sys.stdout if stream is None else stream
    rows = [("frames scored", f"{metrics['n_frames']}"),
            ("success AUC", _fmt(metrics["success_auc"], ".3f")),
            ("precision@20px", _fmt(metrics["precision_at_20"], ".3f")),
            ("mean IoU", _fmt(metrics["mean_iou"], ".3f")),
            ("mean centre error (px)", _fmt(metrics["mean_centre_error"], ".2f"))]
    if metrics.get("n_missing"):
        rows.append(("frames without a box", f"{metrics['n_missing']}"))
    if "fps" in metrics:
        rows.append(("frames per second", _fmt(metrics["fps"], ".1f")))
    width = max(len(r[0]) for r in rows)
    for k, v in rows:
        print(f"{k:<{width}}  {v}", file=stream)


MULTI_TARGET_MODELS = ("phd", "vb-phd", "multi-pf", "gpdm")
#: multi-target models declared as a plate (one sub-graph per target) and their options
PLATE_MODELS = ("multi-pf", "gpdm")
PLATE_OPTIONS = ("parts", "appearance", "scale_noise")


def _memory_limit(args) -> float | None:
    from pgm.app.runner import _parse_bytes

    text = getattr(args, "memory_limit", None)
    return None if text is None else _parse_bytes(text, "--memory-limit")


#: the last frame ``--drop-frames`` may name when the source's length is unknown
MAX_DROPPED_FRAME = 1_000_000


def parse_drop_frames(spec: str | None, n_frames: int | None) -> set[int]:
    """Frame numbers of ``--drop-frames``: ``"A-B,C"`` (1-based, inclusive ranges and
    single frames) or ``"P/L"`` (the last ``L`` frames of every ``P``, which needs the
    sequence length ``n_frames``). A range is cut at the source's last frame (at
    :data:`MAX_DROPPED_FRAME` when its length is unknown); one that starts after it is
    an :class:`InputError`."""
    if spec is None:
        return set()
    text = spec.strip()
    try:
        if "/" in text:
            period, length = (int(v) for v in text.split("/"))
            if not 0 < length < period:
                raise ValueError
            if n_frames is None:
                raise InputError("--drop-frames P/L needs a source of known length; give "
                                 "ranges A-B instead")
            return {f for f in range(1, n_frames + 1) if (f - 1) % period >= period - length}
        out: set[int] = set()
        last = MAX_DROPPED_FRAME if n_frames is None else n_frames
        for part in text.split(","):
            a, _, b = part.strip().partition("-")
            lo, hi = int(a), int(b or a)
            if lo < 1 or hi < lo:
                raise ValueError
            if lo > last:
                where = (f"the source has {n_frames} frames" if n_frames is not None else
                         f"frames after {MAX_DROPPED_FRAME} of a source of unknown length "
                         f"cannot be dropped")
                raise InputError(f"--drop-frames {spec!r}: frame {lo} is past the end "
                                 f"({where})")
            out.update(range(lo, min(hi, last) + 1))  # frames past the end: nothing to drop
        return out
    except InputError:
        raise
    except ValueError:
        raise InputError(f"--drop-frames must be ranges like '50-59,80' or 'P/L' with "
                         f"0 < L < P, got {spec!r}") from None


def cmd_track_multi(args, source, saved=None) -> int:
    from pgm.app.runner import track_multi
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_mot
    from pgm.models import get_model
    from pgm.models.phd import video_params
    from pgm.observation.detections import PublicDetections, make_detector

    what = f"the multi-target model {args.model!r}"
    if args.init is not None:
        raise InputError(f"--init does not apply to {what}")
    plate = args.model in PLATE_MODELS or (saved is not None and bool(saved.plates))
    for opt in MODEL_OPTIONS:
        if _given(args, opt) and (saved is not None or not plate or opt not in PLATE_OPTIONS):
            raise InputError(f"{_flag(opt)} does not apply to {what}")
    if plate:
        for opt in ("dbn", "per_track_noise", "scale_aware", "scores"):
            if _given(args, opt):
                raise InputError(f"{_flag(opt)} applies to phd, vb-phd, not to {what}")
    else:
        for opt in ("drop_frames",):
            if _given(args, opt):
                raise InputError(f"{_flag(opt)} applies to {', '.join(PLATE_MODELS)}, not to "
                                 f"{what}")
    if args.model != "gpdm":
        for opt in ("gpdm", "motion"):
            if _given(args, opt):
                raise InputError(f"{_flag(opt)} applies to gpdm, not to {what}")
    if saved is not None:
        for opt in ("per_track_noise", "scale_aware", "scores"):
            if _given(args, opt):
                raise InputError(f"{_flag(opt)} does not apply to a saved model "
                                 f"({args.model}): its settings are fixed")
    if args.detections is not None and args.detector is not None:
        raise InputError("give either --detections FILE or --detector SPEC, not both")
    if args.detections is not None:
        detector = PublicDetections(args.detections)
    else:
        detector = make_detector(args.detector or "public", source)
    gt_path = args.gt or source.gt_path
    gt = load_mot(gt_path, kind="gt") if gt_path is not None else None
    engine_kwargs = None
    if saved is not None:
        graph = saved
        if args.particles is not None:
            engine_kwargs = {"num_particles": args.particles}
    elif plate:
        import dataclasses

        module = get_model(args.model)
        kwargs = {opt_field: getattr(args, opt) for opt, opt_field in MODEL_OPTIONS.items()
                  if _given(args, opt)}
        if args.particles is not None:
            kwargs["num_particles"] = args.particles
        if "fps" in {f.name for f in dataclasses.fields(module.Params)}:
            kwargs["fps"] = float(source.fps)
        if args.model == "gpdm":
            kwargs["motion"] = args.motion or "gpdm"
            if kwargs["motion"] == "gpdm":
                if args.gpdm is None:
                    raise InputError("--model gpdm needs --gpdm FILE.npz (learn one with 'pgm "
                                     "learn gpdm'), or --motion cv|cv3 for the baselines")
                if not Path(args.gpdm).is_file():
                    raise InputError(f"--gpdm: no such file: {args.gpdm}")
                kwargs["model"] = args.gpdm
            elif args.gpdm is not None:
                raise InputError(f"--gpdm applies to --motion gpdm, not {kwargs['motion']}")
        graph = _build(module, kwargs, args)
    else:
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

        graph = graph.with_factors(DBNLikelihood(graph.output[0], model=args.dbn,
                                                 name="appearance:dbn"),
                                   name=graph.name + "+dbn")
    result = track_multi(source, graph, detector, rng=as_generator(args.seed), out_dir=args.out,
                         gt=gt, write_video=not args.no_video, show_particles=args.show_particles,
                         progress=not args.quiet, max_frames=args.max_frames,
                         camera_motion=args.camera_motion or "auto",
                         engine_kwargs=engine_kwargs,
                         memory_limit_bytes=_memory_limit(args),
                         drop_frames=parse_drop_frames(args.drop_frames, len(source)),
                         record=_record_option(args))
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
                  f"{label:<{width}}  {'n/a' if v is None else v}", file=stream)


def cmd_track(args) -> int:
    from pgm.app.runner import init_box_from_gt, track
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_single_gt
    from pgm.io.video import open_source

    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise InputError(f"--out {args.out} exists and is not a folder")
    source = open_source(args.source)
    saved = None
    if args.model is not None and args.model.endswith(".json"):
        saved = load_model_file(args.model)
    if args.model is None:
        from pgm.models import DEFAULT_SINGLE_OBJECT

        multi = args.detections is not None or args.detector is not None
        args.model = "vb-phd" if multi else DEFAULT_SINGLE_OBJECT
        if not args.quiet:
            print(f"pgm: using model {args.model} (no --model given)", file=sys.stderr)
    if args.model in MULTI_TARGET_MODELS or (saved is not None and _is_multi_target(saved)):
        return cmd_track_multi(args, source, saved)
    what = f"the single-object model {args.model!r}"
    if args.detections is not None or args.detector is not None:
        raise InputError(f"--detections/--detector apply to {', '.join(MULTI_TARGET_MODELS)}, "
                         f"not to {args.model!r}")
    for opt in MULTI_TARGET_OPTIONS:
        if _given(args, opt):
            raise InputError(f"{_flag(opt)} applies to {', '.join(MULTI_TARGET_MODELS)}, "
                             f"not to {what}")
    gt = None
    gt_path = args.gt
    if gt_path is None and args.init is None and source.gt_path is not None:
        gt_path = str(source.gt_path)
        if not args.quiet:
            print(f"pgm: using the sequence's ground truth {gt_path}", file=sys.stderr)
    if gt_path is not None:
        gt = load_single_gt(gt_path)
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
    graph = _load_model_graph(args.model, init_c, args.particles, args)
    if saved is not None and init_c is not None:
        graph = _with_init_box(graph, init_c, args.model)
    result = track(source, graph, rng=as_generator(args.seed), out_dir=args.out, gt=gt,
                   num_particles=args.particles, write_video=not args.no_video,
                   show_particles=args.show_particles, progress=not args.quiet,
                   max_frames=args.max_frames, camera_motion=args.camera_motion or "off",
                   memory_limit_bytes=_memory_limit(args), record=_record_option(args))
    print(f"tracked {len(result.frames)} frames at {result.fps:.1f} frames/s "
          f"(inference only) -> {Path(args.out) / 'tracks.txt'}")
    if result.metrics is not None:
        _print_metrics({**result.metrics, "fps": result.fps})
    return 0


def _eval_form(args) -> str:
    """``"files"`` (``--gt --pred``) or ``"folders"`` (``--gt-dir --pred-dir``); a mix or
    half a pair is an :class:`InputError`."""
    files = [f for f in ("gt", "pred") if getattr(args, f, None) is not None]
    dirs = [f for f in ("gt_dir", "pred_dir") if getattr(args, f, None) is not None]
    if files and dirs:
        raise InputError(f"{' and '.join(_flag(f) for f in files + dirs)} cannot be combined: "
                         f"give --gt FILE --pred FILE (one sequence) or --gt-dir DIR "
                         f"--pred-dir DIR (folders)")
    if dirs:
        if len(dirs) < 2:
            missing = "--pred-dir" if dirs == ["gt_dir"] else "--gt-dir"
            raise InputError(f"{_flag(dirs[0])} needs {missing} (folders are scored in pairs)")
        return "folders"
    if len(files) < 2:
        missing = {"gt": "--pred", "pred": "--gt"}[files[0]] if files else "--gt and --pred"
        raise InputError(f"missing {missing}: give --gt FILE --pred FILE (one sequence) or "
                         f"--gt-dir DIR --pred-dir DIR (folders)")
    return "files"


def _eval_folders(args) -> int:
    """``pgm eval --gt-dir --pred-dir``: every sequence, then the combined and mean rows."""
    from pgm.evaluation.folders import evaluate_mot_folders
    from pgm.evaluation.mot import format_mot_table

    res = evaluate_mot_folders(args.gt_dir, args.pred_dir)
    if args.json:
        print(json.dumps(res, indent=1))
        return 0
    rows = dict(res["sequences"])
    rows["COMBINED"] = res["combined"]
    rows["MEAN"] = res["mean"]
    print(format_mot_table(rows, label="sequence"))
    print(f"{len(res['sequences'])} sequence(s); COMBINED: {res['combined_method']}")
    if res["missing"]:
        print(f"no prediction file (scored as empty): {', '.join(res['missing'])}")
    if res["unmatched"]:
        print(f"prediction files without ground truth (not scored): "
              f"{', '.join(res['unmatched'])}")
    return 0


def cmd_eval(args) -> int:
    """``pgm eval``: one result file (single object or MOT) or a folder of them."""
    from pgm.evaluation.single_object import single_object_metrics
    from pgm.io.annotations import detect_gt_format, load_mot, load_single_gt, load_tracks

    if _eval_form(args) == "folders":
        return _eval_folders(args)
    pred = load_tracks(args.pred)
    if len(pred) == 0:
        raise InputError(f"--pred {args.pred} holds no rows: nothing to evaluate")
    if detect_gt_format(args.gt) == "mot":
        gt_table = load_mot(args.gt, kind="gt")
        if np.unique(gt_table.ids).size > 1 or np.unique(pred.ids).size > 1:
            from pgm.evaluation.mot import evaluate_mot_files

            metrics = evaluate_mot_files(args.gt, args.pred, per_frame=False)
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
    from pgm.io.outputs import prepare_output_file

    out = Path(args.out)
    if out.suffix.lower() not in (".png", ".svg", ".pdf", ".dot"):
        raise InputError(f"--out must end in .png, .svg, .pdf or .dot, got {out.name}")
    graph = _load_model_graph(args.model, np.array([50.0, 50.0, 20.0, 30.0]), None, args)
    out = prepare_output_file(out)
    graph.draw(out)
    print(f"wrote {out}")
    return 0


def cmd_demo(args) -> int:
    from pgm.app.runner import track
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_single_gt
    from pgm.io.outputs import prepare_run_folder
    from pgm.io.video import open_source
    from pgm.models import colour_pf, part_graph, single_object
    from pgm.synthetic import demo_scene

    out = prepare_run_folder(args.out)
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
        folder = prepare_run_folder(folder)
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


def _gpdm_training_trajectories(sequences: list[str]) -> list:
    """Ground-truth trajectories of MOTChallenge folders (frame rate from seqinfo.ini)."""
    from pgm.dynamics.gpdm import gt_trajectories
    from pgm.io.annotations import load_mot
    from pgm.io.video import _read_seqinfo, _seqinfo_number

    trajectories = []
    for seq in sequences:
        folder = Path(seq)
        if not folder.exists():
            raise InputError(f"--train: no such folder: {folder}")
        ini = folder / "seqinfo.ini"
        gt = folder / "gt" / "gt.txt"
        if not folder.is_dir() or not ini.is_file() or not gt.is_file():
            raise InputError(f"--train {folder}: not a MOTChallenge sequence with ground "
                             f"truth (needs seqinfo.ini and gt/gt.txt)")
        info = _read_seqinfo(ini)
        fps = _seqinfo_number(info, "frameRate", ini, integer=False)
        if fps is None:
            raise InputError(f"{ini} has no frameRate (the GPDM's units are box heights "
                             f"per second)")
        table = load_mot(gt, kind="gt")
        try:
            found = gt_trajectories(table, fps=fps, source=info.get("name") or folder.name)
        except ValueError as exc:
            raise InputError(f"{gt}: {one_line(exc)}") from None
        trajectories += found
    return trajectories


def _one_step_rmse(model) -> tuple[float, float]:
    """One-step training RMSE (heights per second) of the GPDM's mean prediction
    ``μ_Y(μ_X(x_t))`` against ``y_{t+1}``, and of repeating ``y_t`` (constant velocity)."""
    lengths = np.asarray(model.lengths)
    last = np.zeros(int(lengths.sum()), dtype=bool)
    last[np.cumsum(lengths) - 1] = True
    i_in = np.flatnonzero(~last)
    y = model.y_mean + model.y_std * np.asarray(model.Y)
    pred = model.mean_y(model.dynamics(model.X[i_in])[0])
    rmse = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    return rmse(pred - y[i_in + 1]), rmse(y[i_in] - y[i_in + 1])


def cmd_learn_gpdm(args) -> int:
    """``pgm learn gpdm``: trajectories → :func:`learn_gpdm` → ``.npz`` (and a plot)."""
    from pgm.core.rng import as_generator
    from pgm.dynamics.gpdm import GPDMSettings, learn_gpdm
    from pgm.io.outputs import prepare_output_file
    from pgm.plotting.gpdm import PLOT_SUFFIXES, plot_latent_space

    out = Path(args.out)
    if out.suffix.lower() != ".npz":
        raise InputError(f"--out must end in .npz, got {out.name}")
    plot = None if args.plot is None else Path(args.plot)
    if plot is not None and plot.suffix.lower() not in PLOT_SUFFIXES:
        raise InputError(f"--plot must end in {', '.join(PLOT_SUFFIXES)}, got {plot.name}")
    out = prepare_output_file(out)
    if plot is not None:
        plot = prepare_output_file(plot, "--plot")
    trajectories = _gpdm_training_trajectories(args.train)
    usable = [t for t in trajectories if len(t) >= 3]
    if len(usable) < 2:
        raise InputError(f"--train gives {len(usable)} usable trajectory(ies) (people seen "
                         f"in at least 10 consecutive frames); at least 2 are needed")
    given = {"latent_dim": args.latent_dim, "mirror": args.mirror,
             "max_iter": args.max_iter}
    settings = GPDMSettings(balanced=args.balanced,
                            **{k: v for k, v in given.items() if v is not None})
    try:
        model = learn_gpdm(usable, settings, as_generator(args.seed))
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(f"--train {' '.join(args.train)}: {one_line(exc)}") from None
    model.save(out)
    if plot is not None:
        plot_latent_space(model, plot)
    gpdm_rmse, cv_rmse = _one_step_rmse(model)
    info = model.info
    stop = "converged" if info.get("converged") else "stopped at the cap"
    print(f"learned a GPDM (d={model.latent_dim}) from {len(usable)} trajectories of "
          f"{len(args.train)} sequence(s): {info.get('n_points')} points in "
          f"{info.get('n_sequences')} sequences, {info.get('iterations')} L-BFGS iterations "
          f"({stop}), objective {info.get('objective', float('nan')):.2f}; one-step training "
          f"RMSE {gpdm_rmse:.3f} heights/s (repeating the last change: {cv_rmse:.3f}); wrote "
          f"{out}" + (f" and {plot}" if plot is not None else ""))
    return 0


def cmd_learn(args) -> int:
    """``pgm learn dbn|gpdm``: dispatch on what is learned."""
    if args.what == "gpdm":
        return cmd_learn_gpdm(args)
    return cmd_learn_dbn(args)


def cmd_learn_dbn(args) -> int:
    """``pgm learn dbn``: train the DBN person likelihood on patches of ``--train``."""
    from pgm.core.rng import as_generator
    from pgm.io.outputs import prepare_output_file
    from pgm.observation.appearance.dbn import DBN, training_set
    from pgm.observation.appearance.features import PatchFeatures

    out = Path(args.out)
    if out.suffix.lower() != ".npz":
        raise InputError(f"--out must end in .npz, got {out.name}")
    out = prepare_output_file(out)
    rng = as_generator(args.seed)
    feats = PatchFeatures()
    X, y = training_set(args.train, rng, every=args.every, features=feats)
    net = DBN()
    net.features_ = feats.to_dict()
    net.fit(X, y, rng, finetune_epochs=args.epochs)
    net.save(out)
    p = net.predict_proba(X)
    acc = float(np.mean((p > 0.5) == y))
    print(f"trained on {len(y)} patches ({int(y.sum())} people) from {len(args.train)} "
          f"sequence(s); training accuracy {acc:.3f}; wrote {out}")
    return 0


COMMANDS = {"track": cmd_track, "eval": cmd_eval, "graph": cmd_graph, "demo": cmd_demo,
            "learn": cmd_learn}

EXIT_INTERNAL = 1


class _OneLine(logging.Formatter):
    """``pgm: warning: <message>``, the message squashed to one line."""

    def format(self, record: logging.LogRecord) -> str:
        return f"pgm: {record.levelname.lower()}: {one_line(record.getMessage())}"


def _quiet_native_logs() -> None:
    """FFmpeg (through OpenCV) and OpenCV print their own lines to the terminal
    (``moov atom not found``); the toolkit reports those failures itself, in one line."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET, read on first use
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    try:
        import cv2

        cv2.setLogLevel(0)  # LOG_LEVEL_SILENT
    except (ImportError, AttributeError):  # pragma: no cover - cv2 is a dependency
        pass


def _ensure_std_streams() -> None:
    """Standard input, output or error closed (``pgm track ... 2>&-``): opened on the
    null device, so that no file a run opens takes descriptor 0, 1 or 2 (FFmpeg's log
    lines would land in it) and the progress bar and messages go nowhere, not to an
    ``AttributeError``."""
    for fd, name, flags in ((0, "stdin", os.O_RDONLY), (1, "stdout", os.O_WRONLY),
                            (2, "stderr", os.O_WRONLY)):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, flags)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        if getattr(sys, name) is None:
            setattr(sys, name, open(fd, "r" if fd == 0 else "w", closefd=False))


def _raise_interrupted(signum, frame):  # noqa: ARG001 - signal handler signature
    raise Interrupted(signum)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pgm`` console script; returns the exit code.

    The one place where failures become messages: an expected failure
    (:func:`pgm.core.errors.user_message`) prints ``pgm: error: <one line>`` and returns 2;
    SIGINT/SIGTERM print one line and return 130/143; anything else is a bug, printed as
    ``pgm: internal error: ...`` and returned as 1 (``--debug`` or ``PGM_DEBUG=1`` shows
    the traceback).
    """
    _ensure_std_streams()
    _quiet_native_logs()
    parser = build_parser()
    args = parser.parse_args(argv)
    debug = args.debug or os.environ.get("PGM_DEBUG") == "1"
    log = logging.getLogger("pgm")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_OneLine())
    log.addHandler(handler)
    old_propagate, log.propagate = log.propagate, False
    if log.level == logging.NOTSET:
        log.setLevel(logging.INFO)
    handlers = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            handlers[sig] = signal.signal(sig, _raise_interrupted)
        except (ValueError, OSError):  # not the main thread: leave signals alone
            pass
    try:
        with warnings.catch_warnings():
            warnings.showwarning = (lambda message, category, filename, lineno, file=None,
                                    line=None: log.warning(one_line(message)))
            commands = dict(COMMANDS)
            for module in _extensions():
                commands.update(module.COMMANDS)
            return commands[args.command](args)
    except KeyboardInterrupt as exc:
        name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
        print(f"pgm: interrupted by {name}; results written so far are kept (run.json says "
              f"\"complete\": false)", file=sys.stderr)
        return 128 + (exc.signum if isinstance(exc, Interrupted) else signal.SIGINT)
    except Exception as exc:  # noqa: BLE001 - every failure ends as one line
        if debug:
            raise
        msg = user_message(exc)
        if msg is not None:
            print(f"pgm: error: {msg}", file=sys.stderr)
            return EXIT_BAD_INPUT
        print(f"pgm: internal error: {type(exc).__name__}: {one_line(exc)} (rerun with "
              f"--debug for the traceback)", file=sys.stderr)
        return EXIT_INTERNAL
    finally:
        for sig, old in handlers.items():
            signal.signal(sig, old)
        log.removeHandler(handler)
        log.propagate = old_propagate
        sys.stdout.flush()


if __name__ == "__main__":
    sys.exit(main())
