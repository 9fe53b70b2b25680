"""Wang et al.'s (2008) error rate against hand-worked frames."""

import numpy as np

from pgm.evaluation.mot import error_rate


def test_error_rate_counts_frames_with_a_miss_tracked_target():
    g = np.array([[0, 0, 10, 10], [20, 0, 10, 10]], float)
    frames_gt = [g, g, g, g[:0], g[:1]]
    frames_pr = [
        g + [1, 0, 0, 0],                      # both tracked (IoU 0.82)
        g[:1],                                 # the second target not reported
        np.array([[0, 0, 10, 10], [26, 0, 10, 10]], float),  # IoU 4/16 = 0.25 < 0.5
        g,                                     # no ground truth: not counted
        np.zeros((0, 4)),                      # the only target not reported
    ]
    assert error_rate(frames_gt, frames_pr) == 3 / 4
    assert error_rate(frames_gt, frames_pr, iou=0.2) == 2 / 4
    assert error_rate([g[:0]], [g]) is None
