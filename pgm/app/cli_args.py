"""What the ``pgm`` commands share: argument types, the parser class, small helpers.

Every argument type gives a one-line message naming its option; :class:`_Parser` turns
argparse's errors into one line and exit 2, and :class:`HelpFormatter` shows every
default.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

from pgm.core.errors import InputError, one_line

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


def _number(name: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None


def _probability(name: str):
    """An argparse type: a number in [0, 1]."""
    def conv(text: str) -> float:
        v = _number(name, text)
        if not 0.0 <= v <= 1.0:  # also false for NaN
            raise argparse.ArgumentTypeError(f"{name} must be a probability in [0, 1], got "
                                             f"{text!r}")
        return v

    return conv


def _finite_float(name: str, low: float = 0.0):
    """An argparse type: a finite number ``>= low``."""
    def conv(text: str) -> float:
        v = _number(name, text)
        if not np.isfinite(v) or v < low:
            raise argparse.ArgumentTypeError(f"{name} must be a finite number >= {low:g}, "
                                             f"got {text!r}")
        return v

    return conv


def _frame_rate(name: str):
    """An argparse type: a frame rate within the sources' own limits
    (:data:`pgm.io.video.MIN_FPS`, :data:`~pgm.io.video.MAX_FPS`)."""
    def conv(text: str) -> float:
        from pgm.io.video import MAX_FPS, MIN_FPS

        v = _number(name, text)
        if not MIN_FPS <= v <= MAX_FPS:  # also false for NaN
            raise argparse.ArgumentTypeError(f"{name} must be a frame rate in [{MIN_FPS:g}, "
                                             f"{MAX_FPS:g}], got {text!r}")
        return v

    return conv


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

    #: the model the arguments name (set by :func:`pgm.app.cli.parse_args`), for messages
    model_name: str | None = None

    def error(self, message: str):
        if message.startswith("unrecognized arguments:") and self.model_name is not None:
            flags = [a for a in message.split(":", 1)[1].split() if a.startswith("--")]
            better = explain_unknown_options(flags, self.model_name) if flags else None
            if better is not None:  # another model's option: an input error of its own
                raise InputError(better)
        self.exit(EXIT_BAD_INPUT, f"pgm: error: {' '.join(message.split())} "
                                  f"(see {self.prog} --help)\n")


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


def _flag(opt: str) -> str:
    return "--" + opt.replace("_", "-")


def _given(args: argparse.Namespace | None, opt: str) -> bool:
    value = getattr(args, opt, None) if args is not None else None
    return value is not None and value is not False


def import_user_code(spec: str, option: str = "--import"):
    """``--import MODULE_OR_FILE``: import a user's module (a dotted name on the path) or
    file (``.py``, imported under its stem) that defines factors, their rules or models,
    so that a saved model using them loads; returns the module. The user asks for this
    code to run; a model file itself never runs any. A failure is a one-line
    :class:`InputError` naming ``option``."""
    import importlib
    import importlib.util

    if not isinstance(spec, str) or not spec:
        raise InputError(f"{option} needs a module name or a .py file")
    path = Path(spec)
    if path.suffix == ".py" or path.exists():
        if not path.exists():
            raise InputError(f"{option} {spec}: no such file")
        if not path.is_file() or path.suffix != ".py":
            raise InputError(f"{option} {spec}: not a .py file")
        name = path.stem
        if not name.isidentifier():
            raise InputError(f"{option} {spec}: {name!r} is not a module name (rename the file)")
        held = sys.modules.get(name)
        if held is not None:
            if Path(getattr(held, "__file__", "") or "").resolve() == path.resolve():
                return held
            raise InputError(f"{option} {spec}: a module named {name!r} is already imported "
                             f"from {getattr(held, '__file__', None) or 'elsewhere'}")
        found = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(found)
        sys.modules[name] = module
        try:
            found.loader.exec_module(module)
        except Exception as exc:  # noqa: BLE001 - the user's code: any failure, one line
            sys.modules.pop(name, None)
            raise InputError(f"{option} {spec}: {type(exc).__name__}: {one_line(exc)}") from None
        return module
    try:
        return importlib.import_module(spec)
    except Exception as exc:  # noqa: BLE001 - the user's code: any failure, one line
        raise InputError(f"{option} {spec}: {type(exc).__name__}: {one_line(exc)}") from None


def user_detector(spec: str):
    """``--detector MODULE:FUNCTION`` (or ``FILE.py:FUNCTION``): the user's function
    imported and wrapped as a :class:`~pgm.observation.detections.CallableDetector`."""
    from pgm.observation.detections import CallableDetector

    module_spec, _, name = spec.rpartition(":")
    module = import_user_code(module_spec, option="--detector")
    fn = getattr(module, name, None)
    if fn is None or not callable(fn):
        raise InputError(f"--detector {spec}: {module_spec} has no function {name!r}")
    return CallableDetector(fn, name=spec)


def scan_imports(argv: list[str]) -> list[str]:
    """The values of every ``--import X`` / ``--import=X`` in ``argv`` (read before the
    model is: its file may name the user's factors and rules)."""
    out = []
    for i, a in enumerate(argv):
        if a == "--import" and i + 1 < len(argv):
            out.append(argv[i + 1])
        elif a.startswith("--import="):
            out.append(a.split("=", 1)[1])
    return out


def load_model_file(path: str | Path):
    """A saved ``model.json`` as a :class:`~pgm.core.graph.FactorGraph` (plain JSON, no
    code runs); every malformation is an :class:`InputError` naming the file."""
    from pgm.core.graph import FactorGraph

    p = Path(path)
    if p.is_dir():
        raise InputError(f"model file {p} is a folder")
    try:
        graph = FactorGraph.load(p)
        from pgm.inference.settings import EngineSettings

        EngineSettings.from_dict(graph.meta.get("engine"))  # its engine settings, checked here
        return graph
    except InputError:
        raise
    except ValueError as exc:
        msg = one_line(exc)
        raise InputError(msg if str(p) in msg else f"model file {p}: {msg}") from None
    except (KeyError, TypeError, AttributeError, IndexError, RecursionError,
            OverflowError) as exc:
        raise InputError(f"model file {p} is malformed: {type(exc).__name__}: "
                         f"{one_line(exc)[:120]}") from None


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
    if metrics.get("n_absent"):
        rows.append(("frames annotated absent", f"{metrics['n_absent']}"))
    lt = metrics.get("long_term")
    if lt is not None and (metrics.get("n_absent") or lt.get("threshold") is not None):
        rows.append(("long-term F-score", _fmt(lt["f_score"], ".3f")))
        rows.append(("  precision / recall", f"{_fmt(lt['precision'], '.3f')} / "
                                             f"{_fmt(lt['recall'], '.3f')}"))
    ab = metrics.get("absence")
    if ab is not None:
        rows.append((f"absence flagged (conf < {ab['threshold']:g})",
                     f"precision {_fmt(ab['precision'], '.3f')}, "
                     f"recall {_fmt(ab['recall'], '.3f')}"))
    if "fps" in metrics:
        rows.append(("frames per second (inference)", _fmt(metrics["fps"], ".1f")))
    width = max(len(r[0]) for r in rows)
    for k, v in rows:
        print(f"{k:<{width}}  {v}", file=stream)


def _print_mot_metrics(m: dict, stream=None) -> None:
    stream = sys.stdout if stream is None else stream
    keys = [("MOTA", "mota"), ("IDF1", "idf1"), ("HOTA", "hota"), ("MOTP (IoU)", "motp"),
            ("ID switches", "id_switches"), ("FP", "fp"), ("FN", "fn"),
            ("OSPA(50,1) px", "ospa_50_1"), ("OSPA(100,2) px", "ospa_100_2"),
            ("OSPA2(50,1) px", "ospa2"), ("|cardinality error|", "mean_abs_cardinality_error"),
            ("frames per second (inference)", "fps")]
    width = max(len(k) for k, _ in keys)
    for label, key in keys:
        if key in m:
            v = m[key]
            print(f"{label:<{width}}  {v:.3f}" if isinstance(v, float) else
                  f"{label:<{width}}  {'n/a' if v is None else v}", file=stream)


def _memory_limit(args) -> float | None:
    from pgm.app.memory import _parse_bytes

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


def explain_unknown_options(flags: list[str], model: str | None) -> str | None:
    """A message for options the chosen model does not take, naming the models that do
    (``None`` when some flag is no model's option)."""
    from pgm.models import option_owners

    owners = {flag: [name for name, _ in pairs] for flag, pairs in option_owners().items()}
    bases = [flag.split("=", 1)[0] for flag in flags]
    if not bases or any(b not in owners for b in bases):
        return None
    what = f"model {model!r}" if model and not model.endswith(".json") else \
        f"a saved model ({model}): its factors are fixed" if model else "this model"
    takers = sorted({n for b in bases for n in owners[b]})
    verb = "does" if len(bases) == 1 else "do"
    return (f"{', '.join(bases)} {verb} not apply to {what} (models that take "
            f"{'it' if len(bases) == 1 else 'them'}: {', '.join(takers)})")
