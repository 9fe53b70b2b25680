"""``pgm eval``, ``pgm graph`` and ``pgm learn``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from pgm.core.errors import InputError, one_line

from .cli_args import (
    _flag,
    _int_at_least,
    _Parser,
    _path,
    _positive_int,
    _print_metrics,
    _print_mot_metrics,
    load_model_file,
)
from .cli_track import model_values


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

    res = evaluate_mot_folders(args.gt_dir, args.pred_dir,
                               all_sequences=getattr(args, "all_sequences", False))
    if args.json:
        print(json.dumps(res, indent=1))
        return 0
    rows = dict(res["sequences"])
    rows["COMBINED"] = res["combined"]
    rows["MEAN"] = res["mean"]
    print(format_mot_table(rows, label="sequence"))
    print(f"{len(res['sequences'])} sequence(s); COMBINED: {res['combined_method']}")
    if res["missing"]:
        how = ("scored as empty" if res["all_sequences"] else
               "not scored; --all-sequences scores them as empty")
        print(f"no prediction file ({how}): {', '.join(res['missing'])}")
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
    # the result file's confidences (column 7) give the long-term measures, and the
    # frames it leaves out (no row, or a row of NaN: a run's --lost-below) count as
    # reported absent; a file without varying confidences reports every box it has
    conf = pred.conf if np.all(np.isfinite(pred.conf)) and np.unique(pred.conf).size > 1 \
        else (np.ones(len(pred)) if gt.absent.size else None)
    metrics = single_object_metrics(gt, pred.frames, pred.boxes, conf)
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
    if args.model.endswith(".json"):
        graph, note = load_model_file(args.model), ""
    else:
        config = args.model_config
        try:
            graph, note = config.example_graph(model_values(args, config))
        except InputError:
            raise
        except (ValueError, TypeError) as exc:
            raise InputError(f"model {config.name!r}: {one_line(exc)}") from None
    out = prepare_output_file(out)
    graph.draw(out)
    print(f"wrote {out}" + (f" ({note})" if note else ""))
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


def add_learn_parser(sub) -> None:
    """The ``pgm learn`` sub-parser: ``dbn`` and ``gpdm``."""
    lp = sub.add_parser("learn", help="learn model parameters from annotated sequences")
    lsub = lp.add_subparsers(dest="what", required=True, parser_class=_Parser)
    ld = lsub.add_parser("dbn", help="train the deep-belief-network person likelihood")
    ld.add_argument("--train", type=_path("--train"), nargs="+", required=True,
                    help="MOTChallenge sequence folders with gt/gt.txt (never the one you "
                         "will evaluate on)")
    ld.add_argument("--out", type=_path("--out"), required=True, help="output .npz file")
    ld.add_argument("--every", type=_positive_int("--every"), default=3,
                    help="use every K-th annotated frame")
    ld.add_argument("--seed", type=_int_at_least("--seed", 0), default=0, metavar="S",
                    help="seed of the patch sampling and the network's initial weights")
    ld.add_argument("--epochs", type=_positive_int("--epochs"), default=40,
                    help="fine-tuning epochs")
    _learn_gpdm_options(lsub)


#: defaults of ``pgm learn gpdm`` shown in its help; the values used are
#: :class:`pgm.dynamics.gpdm.GPDMSettings`'s (read when the command runs, so that building
#: the parser does not import torch; a test keeps the two equal)
GPDM_HELP_DEFAULTS = {"latent_dim": 2, "mirror": False, "max_iter": 200}


def _learn_gpdm_options(lsub) -> None:
    """The ``pgm learn gpdm`` sub-parser."""
    d = GPDM_HELP_DEFAULTS
    lg = lsub.add_parser(
        "gpdm", help="learn a Gaussian-process dynamical model of people's motion",
        description="Learn a GPDM (Wang, Yin & Man 2008) from the ground-truth trajectories of\n"
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
    lg.add_argument("--seed", type=_int_at_least("--seed", 0), default=0, metavar="S",
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
