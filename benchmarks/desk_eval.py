"""A long synthetic single-object video: the default against the peers and the scale
filter.

:func:`pgm.synthetic.scenes.desk_scene` renders a textured cube turned by hand under a
desk lamp (320x240 grey, 1344 frames: lighting, in- and out-of-plane rotation, scale
change), the kind of sequence the shared data lacks. Each seed is one video; every
config runs on it from the first ground-truth box (``--seeds`` runs per video, tracker
seeds 0..S-1, a video's AUC their mean), and OpenCV CSRT and MIL run on the same frames
(written to a temporary folder; the peer virtualenv,
``bash benchmarks/peers/setup_env.sh``; without it, MIL alone runs in this process).
Success AUC per video and its mean.

    python benchmarks/desk_eval.py [--videos 4] [--seeds 1] [--frames 1344] [--background 0.3]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, single_thread  # noqa: E402

single_thread()

import appearance_eval as ae  # noqa: E402
from _peers import peer_python  # noqa: E402

from pgm.app.runner import init_box_from_gt  # noqa: E402
from pgm.io.annotations import SingleTrack  # noqa: E402
from pgm.synthetic.scenes import desk_scene  # noqa: E402

CONFIGS = [("DEFAULT: cf, scale levels, jumps, re-detection", ae.DEFAULT),
           (ae.CONTEXT, ae.DEFAULT | dict(appearance="cf(context_rate=0.05)")),
           ("  + scale filter (cf+scale)", ae.DEFAULT | dict(appearance="cf+scale")),
           ("  size by the scale filter alone (cf(scales=1)+scale)",
            ae.DEFAULT | dict(appearance="cf(scales=1)+scale"))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--videos", type=int, default=4, help="seeds 0..N-1, one video each")
    ap.add_argument("--frames", type=int, default=1344)
    ap.add_argument("--seeds", type=int, default=1,
                    help="tracker seeds per video (0..S-1; a video's AUC is their mean)")
    ap.add_argument("--background", type=float, default=0.3,
                    help="the desk's texture (1: as strong as the cube's)")
    ap.add_argument("--appearance", action="append", default=[], metavar="CUES",
                    help="one more row: the default with this appearance string (repeat)")
    ap.add_argument("--no-peers", action="store_true")
    args = ap.parse_args()
    configs = CONFIGS + [(f"  appearance {a}", ae.DEFAULT | dict(appearance=a))
                         for a in args.appearance]
    with tempfile.TemporaryDirectory(prefix="pgm-desk-") as tmp:
        tasks = []
        for seed in range(args.videos):
            seq = desk_scene(seed, args.frames, background=args.background)
            paths = []
            for k, img in enumerate(seq.frames):
                p = Path(tmp) / f"v{seed}" / f"{k + 1:05d}.png"
                p.parent.mkdir(exist_ok=True)
                cv2.imwrite(str(p), img)
                paths.append(p)
            gt = SingleTrack(np.arange(1, args.frames + 1), seq.boxes)
            tasks.append(([(k + 1, img) for k, img in enumerate(seq.frames)], gt,
                          init_box_from_gt(gt, 1), paths))
        rows = []
        per: dict[str, list] = {}  # row label -> [(AUC, fps) per video]
        for label, overrides in configs:
            for task in tasks:
                got = ae.run_config([task], overrides, args.seeds)
                per.setdefault(label, []).append((float(np.mean(got.aucs)), got.median_fps))
        if not args.no_peers:
            if peer_python() is None:
                print(ae.SETUP_HINT + "; MIL alone runs here")
            peers = ae.run_peers if peer_python() is not None else ae.run_mil_here
            for task in tasks:
                for name, got in peers([task]).items():
                    per.setdefault(f"OpenCV {name}", []).append((float(np.mean(got.aucs)),
                                                                 got.median_fps))
        rows = [[label] + [f"{a:.3f}" for a, _ in vals]
                + [f"{np.mean([a for a, _ in vals]):.3f}",
                   float(np.median([f for _, f in vals]))] for label, vals in per.items()]
    print_table(["tracker"] + [f"video {s}" for s in range(args.videos)] + ["mean", "frames/s"],
                rows, title=f"desk_scene: {args.videos} videos x {args.frames} frames, "
                            f"background {args.background:g}; success AUC (tracker seeds "
                            f"0-{args.seeds - 1})")


if __name__ == "__main__":
    main()
