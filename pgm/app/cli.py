"""The ``pgm`` command line.

::

    pgm track SOURCE [--model NAME | --model FILE.json] [the model's options]
              (--init X,Y,W,H | --gt FILE)        one object
              [--detections FILE | --detector SPEC] [--drop-frames A-B,...|P/L]
                                                  many targets
              --out DIR [--particles N] [--seed S] [--no-video] [--show-particles]
    pgm eval --gt FILE --pred DIR/tracks.txt [--json]
    pgm eval --gt-dir GT --pred-dir PRED [--json]
    pgm graph NAME [the model's options] --out FILE.{png,svg,pdf,dot}
    pgm learn WHAT --train SEQ [SEQ ...] --out FILE.npz
    pgm demo --out DIR

Bad input (a missing or corrupt video, a malformed box or ground-truth file, a bad
parameter, a path the file system refuses, a run larger than the memory cap) gets a
one-line ``pgm: error: ...`` and exit code 2, never a traceback: :func:`main` is the one
place that maps failures to messages (through :func:`pgm.core.errors.user_message`).
SIGINT and SIGTERM stop a run the same way (rows kept, video finalised, ``run.json``
says ``"complete": false``; exit 130 or 143). Warnings are one line each,
``pgm: warning: ...`` (the ``logging`` logger ``pgm``); FFmpeg's and OpenCV's own log
lines are silenced.

The command line knows no model by name: models are found through the ``pgm.models``
entry points and declare their own options (:mod:`pgm.models.config`,
:mod:`pgm.app.cli_track`); ``pgm track --model NAME --help`` lists a model's options.
The CLI sits on top of everything and may import :mod:`pgm.models`: imports otherwise go
one way, ``models → inference → pgm``, and a test of the code base enforces it.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import traceback
import warnings

from pgm.core.errors import InputError, Interrupted, interrupt, one_line, user_message

from .cli_args import (
    EXIT_BAD_INPUT,
    NUMBER_LIST_OPTIONS,
    HelpFormatter,
    _finite_float,
    _frame_rate,
    _given,
    _int_at_least,
    _int_in,
    _Parser,
    _path,
    _positive_int,
    _probability,
    _record_options,
    import_user_code,
    load_model_file,
    parse_box,
    parse_drop_frames,
    scan_imports,
)
from .cli_tools import GPDM_HELP_DEFAULTS, add_learn_parser
from .cli_track import add_model_options, default_model

__all__ = ["main", "build_parser", "parse_args", "parse_box", "model_config_for",
           "load_model_file", "parse_drop_frames", "COMMANDS", "EXTENSIONS", "HelpFormatter",
           "NUMBER_LIST_OPTIONS", "EXIT_BAD_INPUT", "_given", "_path", "_positive_int",
           "_int_in", "_finite_float", "_int_at_least", "GPDM_HELP_DEFAULTS"]


def _video_scale(text: str) -> float:
    """``--video-scale``: a number in (0, 1] (:func:`pgm.io.annotated_video.video_scale`)."""
    from pgm.io.annotated_video import video_scale

    try:
        return video_scale((1, 1), float(text))
    except (ValueError, InputError):
        raise argparse.ArgumentTypeError(f"must be a number in (0, 1], got {text!r}") from None


def build_parser(model_config=None) -> argparse.ArgumentParser:
    """The argument parser of ``pgm``; ``model_config`` adds that model's options to
    ``pgm track`` and ``pgm graph`` (:func:`parse_args` finds it from the arguments)."""
    from pgm.models import DEFAULT_MULTI_TARGET, DEFAULT_SINGLE_OBJECT, model_names

    names = ", ".join(model_names())
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
                   help=f"model name ({names}) or a saved model .json; default: "
                        f"{DEFAULT_SINGLE_OBJECT} for one object, or {DEFAULT_MULTI_TARGET} "
                        f"when --detections/--detector is given or the source has "
                        f"det/det.txt (a video: beside it, in a MOTChallenge folder); "
                        f"'pgm track --model NAME --help' lists that model's options")
    init = t.add_mutually_exclusive_group()
    init.add_argument("--init", metavar="X,Y,W,H",
                      help="box in frame 1: top-left corner and size, 1-based like MOT/OTB; "
                           "may start left of or above the image, e.g. --init -3,10,20,20 "
                           "(default: frame 1 of --gt, else of the sequence's own ground "
                           "truth)")
    t.add_argument("--gt", type=_path("--gt"), metavar="FILE",
                   help="ground-truth file: initialises from frame 1 when --init is absent "
                        "and writes metrics.json (default: the sequence's own, if any, "
                        "unless --init gives the object: then only with --gt)")
    t.add_argument("--gt-id", type=_int_at_least("--gt-id", 0), default=None, metavar="ID",
                   help="single object with a MOTChallenge ground truth of several people: "
                        "the identity to follow and score (default: none; with several "
                        "people and no --init the run is refused)")
    t.add_argument("--out", type=_path("--out"), required=True, help="output folder")
    _import_option(t)
    t.add_argument("--particles", type=_positive_int("--particles"), default=None,
                   help="particles per variable (default: the model's)")
    add_model_options(t, model_config)
    t.add_argument("--seed", type=_int_at_least("--seed", 0), default=0, metavar="S",
                   help="seed of the run's random numbers; the same seed gives the same "
                        "results")
    t.add_argument("--no-video", action="store_true", help="do not write annotated.mp4")
    t.add_argument("--show-particles", action="store_true",
                   help="draw particles in the annotated video")
    t.add_argument("--max-frames", type=_positive_int("--max-frames"), default=None,
                   metavar="K", help="track the first K frames only (default: every frame)")
    t.add_argument("--fps", type=_frame_rate("--fps"), default=None, metavar="F",
                   help="the video's frame rate, where the source does not say it (an image "
                        "folder without seqinfo.ini, e.g. UAV123@10fps: --fps 10); models "
                        "whose constants are in seconds read it (default: the source's, "
                        "else none)")
    t.add_argument("--camera-motion", choices=("auto", "on", "off"), default=None,
                   help="global-motion compensation of every target's prediction: auto (on "
                        "frames where the camera moves; the default for multi-target "
                        "models), on, off (the default for one object, whose camera "
                        "usually follows it)")
    t.add_argument("--detections", type=_path("--detections"), metavar="FILE",
                   help="multi-target models: a MOTChallenge det.txt to use as measurements "
                        "(default: none; see --detector)")
    t.add_argument("--drop-frames", default=None, metavar="SPEC",
                   help="models with a plate: withhold frames to simulate missing ones (predicted "
                        "through, still scored): ranges 'A-B,C-D' (1-based, inclusive) or "
                        "'P/L' (the last L of every P frames), e.g. '50-59' or '30/10' "
                        "(default: none)")
    t.add_argument("--detector", default=None,
                   help="multi-target models: 'public' (the sequence's det/det.txt, default), "
                        "'public:MIN_SCORE', 'mog2' (background subtraction), 'hog' "
                        "(OpenCV's HOG people detector, where the installed OpenCV has it) "
                        "or your own "
                        "detector, 'MODULE:FUNCTION' or 'FILE.py:FUNCTION' (a function from "
                        "a BGR frame to boxes x,y,w,h and scores; docs/tutorials/"
                        "16_your_own_detector.py)")
    t.add_argument("--lost-below", type=_probability("--lost-below"), default=None,
                   metavar="P",
                   help="single object: frames whose calibrated confidence is below P are "
                        "written to tracks.txt as empty (the target reported lost), and "
                        "metrics.json says how well that flags the frames where the box "
                        "misses the target (default: every frame written)")
    t.add_argument("--trails", type=_int_at_least("--trails", 0), default=0, metavar="N",
                   help="draw each track's last N centres in annotated.mp4 (default: 0, none)")
    t.add_argument("--video-scale", type=_video_scale, default=None, metavar="S",
                   help="write annotated.mp4 at this scale of the frames, in (0, 1] "
                        "(default: so that its long side is at most 1280 px)")
    t.add_argument("--quiet", action="store_true",
                   help="print nothing but errors (no progress bar, summary or metrics table; "
                        "the files are written as always)")
    t.add_argument("--memory-limit", default=None, metavar="SIZE",
                   help="refuse a run whose estimated memory exceeds SIZE (e.g. 8G); "
                        "default: PGM_MEMORY_LIMIT, else 80%% of the physical memory")
    _record_options(t)

    e = sub.add_parser(
        "eval", help="score a tracks.txt (or a folder of results) against ground truth",
        description="Score one result file against its ground truth (--gt FILE --pred FILE:\n"
                    "single object (OTB) or MOT metrics), or every sequence of a folder\n"
                    "(--gt-dir DIR --pred-dir DIR, MOTChallenge layout: GT/<SEQ>/gt/gt.txt\n"
                    "or GT/<SEQ>.txt against PRED/<SEQ>.txt). With folders, the sequences\n"
                    "with a prediction file are scored and the others listed (--all-sequences:\n"
                    "scored as empty predictions); COMBINED scores them as one (counts summed,\n"
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
    e.add_argument("--all-sequences", action="store_true",
                   help="with --gt-dir: score every ground-truth sequence, one without a "
                        "prediction file as an empty prediction, as a benchmark server does "
                        "(default: only the sequences predicted)")
    e.add_argument("--json", action="store_true", help="print JSON instead of a table")

    g = sub.add_parser("graph", help="draw a model's factor graph")
    g.add_argument("model", help=f"model name ({names}) or a model .json")
    g.add_argument("--out", type=_path("--out"), required=True, help="FILE.png, .svg, .pdf or .dot")
    _import_option(g)
    add_model_options(g, model_config)

    add_learn_parser(sub)

    d = sub.add_parser("demo", help="render a synthetic scene, track it, write every output")
    d.add_argument("--out", type=_path("--out"), required=True, help="output folder")
    d.add_argument("--seed", type=_int_at_least("--seed", 0), default=0, metavar="S",
                   help="seed of the synthetic scene and of the trackers")
    d.add_argument("--frames", type=_positive_int("--frames"), default=90, metavar="K",
                   help="length of the synthetic scene")
    d.add_argument("--particles", type=_positive_int("--particles"), default=100,
                   metavar="N", help="particles of the colour particle filter")
    d.add_argument("--quiet", action="store_true", help="print nothing but errors")
    for module in _extensions():
        module.add_parser(sub)
    return p


def _import_option(parser) -> None:
    parser.add_argument("--import", dest="imports", action="append", default=[],
                        metavar="MODULE_OR_FILE",
                        help="import a module or .py file of your own factors, rules or "
                             "models first (a saved model using them then loads); "
                             "repeatable (default: none)")


#: modules adding sub-commands: each has ``add_parser(subparsers)`` and ``COMMANDS``
#: (name → ``cmd(args) -> int``), and imports nothing heavy at module level
EXTENSIONS: tuple[str, ...] = ("pgm.app.view", "pgm.app.experiment", "pgm.app.report")


def _extensions():
    import importlib

    return [importlib.import_module(m) for m in EXTENSIONS]


#: the commands: name → ``module:function`` (imported when the command runs, so that
#: ``--help`` and the light commands start fast)
COMMANDS = {"track": "pgm.app.cli_track:cmd_track", "eval": "pgm.app.cli_tools:cmd_eval",
            "graph": "pgm.app.cli_tools:cmd_graph", "demo": "pgm.app.demo:cmd_demo",
            "learn": "pgm.app.cli_tools:cmd_learn"}


def _command(target):
    if callable(target):
        return target
    import importlib

    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


def _probe(argv: list[str]) -> argparse.Namespace | None:
    """The arguments as far as the parser without model options reads them (no help, no
    error: what it cannot read now is reported by the full parse). Models' options are
    set aside first, so that their values are not taken for the source or the model;
    ``--out`` is supplied if missing, so that ``--help`` alone still finds the source."""
    import contextlib
    import io

    base = build_parser()
    probe = [a for a in argv if a not in ("-h", "--help")]
    command = next((a for a in probe if a in ("track", "graph")), None)
    if command is not None:
        sub = next(a for a in base._actions if isinstance(a, argparse._SubParsersAction))
        known = set(sub.choices[command]._option_string_actions)
        probe = _without_model_options(probe, known)
        if "--out" not in probe and not any(a.startswith("--out=") for a in probe):
            probe += ["--out", "-"]
    try:
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            return base.parse_known_args(probe)[0]
    except SystemExit:
        return None


def _without_model_options(argv: list[str], known: set[str]) -> list[str]:
    """``argv`` less the options (and their values) that some model declares and the
    command itself does not know (the models are imported only if there are any)."""
    unknown = [a.split("=", 1)[0] for a in argv if a.startswith("--")
               and a.split("=", 1)[0] not in known]
    if not unknown:
        return argv
    from pgm.models import option_owners

    flag_only = {flag: pairs[0][1].flag_only for flag, pairs in option_owners().items()}
    out, i = [], 0
    while i < len(argv):
        a = argv[i]
        flag = a.split("=", 1)[0]
        if a.startswith("--") and flag not in known and flag in flag_only:
            i += 1 if (flag_only[flag] or "=" in a) else 2
            continue
        out.append(a)
        i += 1
    return out


def _scan_model(argv: list[str], command: str) -> str | None:
    """The model named in ``argv`` read token by token: ``--model NAME`` (``track``) or
    the first word after ``graph``."""
    for i, a in enumerate(argv):
        if command == "track":
            if a == "--model" and i + 1 < len(argv):
                return argv[i + 1]
            if a.startswith("--model="):
                return a.split("=", 1)[1]
        elif a == "graph":
            return next((b for b in argv[i + 1:] if not b.startswith("-")), None)
    return None


def model_config_for(argv: list[str]):
    """The config of the model that ``argv`` (``track`` or ``graph``) names, or that
    ``pgm track`` runs by default; ``None`` for a saved model ``.json`` or another
    command. An unknown model is an :class:`InputError`."""
    return _model_of(argv)[0]


def _model_of(argv: list[str]) -> tuple[object | None, str | None]:
    """``(config, name)`` of the model ``argv`` names (the name alone for a saved
    ``.json``; ``(None, None)`` for a command without a model)."""
    from pgm.models import get_config

    ns = _probe(argv)
    command = getattr(ns, "command", None) or next(
        (a for a in argv if a in ("track", "graph")), None)
    if command not in ("track", "graph"):
        return None, None
    model = getattr(ns, "model", None)
    if model is None and ns is None:  # the probe failed
        model = _scan_model(argv, command)
    if model is None:
        if command == "graph":
            return None, None
        hint = any(a.split("=", 1)[0] in ("--detections", "--detector") for a in argv)
        model = default_model(getattr(ns, "source", None), hint)
    if model.endswith(".json"):
        return None, model
    try:
        return get_config(model), model
    except ValueError as exc:
        raise InputError(one_line(exc)) from None


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """``pgm``'s arguments, read in two passes: the first finds the model, the second
    reads its options too (``args.model_config``: its :class:`~pgm.models.config.ModelConfig`,
    ``None`` for a saved ``.json``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    for spec in scan_imports(argv):  # the user's factors and rules, before any model
        import_user_code(spec)
    config, name = _model_of(argv)
    parser = build_parser(config)
    parser.model_name = name
    args = parser.parse_args(argv)
    if not hasattr(args, "model_config"):
        args.model_config = config
    return args


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
    interrupt(signum)  # raises Interrupted, or holds it to the end of an uninterrupted block


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
    try:
        args = parse_args(argv)
    except InputError as exc:  # a model that cannot be found or loaded, or its options
        print(f"pgm: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:  # Ctrl-C while the models load: nothing has run yet
        print("pgm: interrupted by SIGINT before anything ran", file=sys.stderr)
        return 128 + signal.SIGINT
    args.argv = ["pgm", *(sys.argv[1:] if argv is None else [str(a) for a in argv])]
    debug = args.debug or os.environ.get("PGM_DEBUG") == "1"
    log = logging.getLogger("pgm")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_OneLine())
    log.addHandler(handler)
    old_propagate, log.propagate = log.propagate, False
    old_level = log.level
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
            if not getattr(args, "quiet", False):
                return _command(commands[args.command])(args)
            # --quiet: nothing but errors (no progress, summary, table or notice)
            log.setLevel(logging.ERROR)
            with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
                return _command(commands[args.command])(args)
    except KeyboardInterrupt as exc:
        name = exc.name if isinstance(exc, Interrupted) else "SIGINT"
        print(f"pgm: interrupted by {name}; results written so far are kept (run.json says "
              f"\"complete\": false)", file=sys.stderr)
        return 128 + (exc.signum if isinstance(exc, Interrupted) else signal.SIGINT)
    except Exception as exc:  # noqa: BLE001 - every failure ends as one line
        if debug:  # the traceback, then the same line and exit code (the run's threads
            # are released with the exception here, not left running at interpreter exit)
            traceback.print_exc(file=sys.stderr)
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
        log.setLevel(old_level)
        sys.stdout.flush()


if __name__ == "__main__":
    sys.exit(main())
