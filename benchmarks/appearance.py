"""Appearance factors benchmark: µs per candidate box for every likelihood factor.

For each factor of :mod:`pgm.observation.appearance.likelihoods` (and the DBN's patch features
plus network), ``N`` = 100 and 1000 boxes (40x80, centres scattered around the first
PETS09-S2L1 person, the frame resized to 384x288 and 768x576 as in
``benchmarks/likelihood.py``) are scored on a *fresh* ``FrameContext`` per call, so the
per-frame work (quantisation, integral images, lookup tables) is included: this is
what one factor costs per frame. The reference is per-box ``cv2.calcHist`` on the HSV
ROI (16x4x4 bins) + Bhattacharyya, timed in the same run; ``ratio`` is its time over
the factor's. ``GMM-KL literal`` fits a scikit-learn mixture per box (the seed's
method), at N = 100 on the small frame only. Best of ``--repeats``; one thread.

    python benchmarks/appearance.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, single_thread  # noqa: E402

single_thread()

import cv2  # noqa: E402
from likelihood import best_of, int_bounds, load_frame, make_boxes, per_box_calchist_hsv  # noqa: E402

from pgm.core.frame import FrameContext  # noqa: E402
from pgm.observation.appearance.likelihoods import (  # noqa: E402
    ColourContrastLikelihood,
    ColourHistogramLikelihood,
    FragmentsLikelihood,
    GMMKLLikelihood,
    GradientLikelihood,
    RotationInvariantLikelihood,
    TemplateLikelihood,
)


def tiny_dbn(path: Path, rng) -> str:
    """A DBN trained for a few epochs on random features: its cost, not its accuracy."""
    from pgm.observation.appearance.dbn import DBN
    from pgm.observation.appearance.features import PatchFeatures

    dim = PatchFeatures().dim
    X = rng.random((200, dim)).astype(np.float32)
    y = (rng.random(200) < 0.5).astype(np.float32)
    DBN().fit(X, y, rng, rbm_epochs=1, finetune_epochs=1).save(path)
    return str(path)


def factories(dbn_path: str):
    from pgm.observation.appearance.dbn import DBNLikelihood

    return [
        ("colour perez (Pérez et al. 2002)", lambda: ColourHistogramLikelihood("o")),
        ("colour hsv 16x4x4", lambda: ColourHistogramLikelihood("o", layout="hsv")),
        ("colour rgb 8x8x8", lambda: ColourHistogramLikelihood("o", layout="rgb")),
        ("fragments 3x3", lambda: FragmentsLikelihood("o")),
        ("gradient 9x(3x3)", lambda: GradientLikelihood("o")),
        ("GMM-KL shared", lambda: GMMKLLikelihood("o")),
        ("rings (rot.-inv.)", lambda: RotationInvariantLikelihood("o")),
        ("contrast", lambda: ColourContrastLikelihood("o")),
        ("template (NCC 12x24)", lambda: TemplateLikelihood("o")),
        ("DBN (colour+HOG)", lambda: DBNLikelihood("o", model=dbn_path,
                                                   position_indices=(0, 1))),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    tmp = tempfile.TemporaryDirectory()
    dbn_path = tiny_dbn(Path(tmp.name) / "dbn.npz", rng)
    for size in ((384, 288), (768, 576)):
        frame, point, what = load_frame(*size)
        box = np.array([point[0], point[1], 40.0, 80.0])
        hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
        rows = []
        for n in (100, 1000):
            boxes = make_boxes(np.random.default_rng(n), n, point, (40, 80), 15.0)
            bounds = int_bounds(boxes, frame.shape[0], frame.shape[1])
            q = cv2.calcHist([hsv[bounds[2][0]:bounds[3][0], bounds[0][0]:bounds[1][0]]],
                             [0, 1, 2], None, [16, 4, 4], [0, 180, 0, 256, 0, 256])
            t_ref = best_of(args.repeats, per_box_calchist_hsv, hsv, bounds, q) / n * 1e6
            rows.append([n, "cv2.calcHist per box (HSV)", t_ref, 1.0, "-"])
            items = factories(dbn_path)
            if n == 100 and size == (384, 288):
                items.append(("GMM-KL literal (fit per box)",
                              lambda: GMMKLLikelihood("o", method="literal")))
            for label, make in items:
                f = make()
                x = boxes if not label.startswith("DBN") else boxes[:, :2] + [0, 40]
                f.initialize(FrameContext(0, frame), box if not label.startswith("DBN")
                             else np.array([box[0], box[1] + 40]))

                def call(f=f, x=x, frame=frame):
                    return f.log_likelihood(x, FrameContext(1, frame))

                reps = 1 if "literal" in label else args.repeats
                t = best_of(reps, call) / n * 1e6
                tracemalloc.start()
                call()
                peak = tracemalloc.get_traced_memory()[1] / 2**20
                tracemalloc.stop()
                rows.append([n, label, t, t_ref / t, f"{peak:.2f}"])
        print_table(["N", "factor", "µs/box", "ratio (calcHist/ours)", "peak MiB"], rows,
                    title=f"{size[0]}x{size[1]} ({what}); fresh frame per call, best of "
                          f"{args.repeats}")


if __name__ == "__main__":
    main()
