"""The one IoU of the package (pgm.core.boxes): pairwise on centre boxes and elementwise on
top-left boxes, against hand-worked values."""

import numpy as np

from pgm.core.boxes import cxcywh_to_xywh, iou_matrix, iou_xywh


def test_iou_by_hand():
    a = np.array([0.0, 0.0, 10.0, 10.0])
    assert iou_xywh(a, a) == 1.0
    assert iou_xywh(a, a + [5, 0, 0, 0]) == 50.0 / 150.0
    assert iou_xywh(a, a + [5, 5, 0, 0]) == 25.0 / 175.0
    assert iou_xywh(a, a + [10, 0, 0, 0]) == 0.0  # touching
    assert iou_xywh(a, np.array([2.0, 2.0, 4.0, 4.0])) == 16.0 / 100.0  # inside


def test_pairwise_centre_iou_is_the_elementwise_one():
    rng = np.random.default_rng(0)
    a = np.column_stack([rng.uniform(0, 100, (7, 2)), rng.uniform(5, 40, (7, 2))])
    b = np.column_stack([rng.uniform(0, 100, (5, 2)), rng.uniform(5, 40, (5, 2))])
    m = iou_matrix(a, b)
    e = iou_xywh(cxcywh_to_xywh(a)[:, None, :], cxcywh_to_xywh(b)[None, :, :])
    assert m.shape == (7, 5)
    np.testing.assert_allclose(m, e, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(iou_matrix(b, a), m.T, rtol=1e-12, atol=1e-15)
    assert ((m >= 0) & (m <= 1)).all()


def test_degenerate_boxes_overlap_nothing():
    good = np.array([[10.0, 10.0, 4.0, 4.0]])
    bad = np.array([[10.0, 10.0, 0.0, 0.0], [np.nan, 10.0, 4.0, 4.0],
                    [10.0, 10.0, np.inf, 4.0]])
    np.testing.assert_array_equal(iou_matrix(good, bad), [[0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(iou_xywh(cxcywh_to_xywh(good), cxcywh_to_xywh(bad)),
                                  [0.0, 0.0, 0.0])
    assert iou_matrix(np.zeros((0, 4)), good).shape == (0, 1)
