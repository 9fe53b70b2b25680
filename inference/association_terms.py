"""The association's pieces: what a round of
:class:`~pgm.factors.association.DetectionAssociation` maximises and which pairs it allows,
each a named function of :class:`AssociationInputs` (a round's
:class:`~pgm.factors.association.RoundPlan`).

A round's *affinity* ``a(inputs, **args) -> (K, M)`` is what a match must reach (the
round's threshold); a *term* ``f(inputs, **args) -> (K, M)`` adds ``weight × f`` to what
the round maximises; a *gate* ``g(inputs, **args) -> (K, M)`` allows only the pairs where
it is true. The built-in pieces are :func:`iou_affinity` (SORT's, ByteTrack's, OC-SORT's
recovery against the last detection, BoT-SORT's times the score, C-BIoU's buffered),
:func:`momentum` (OC-SORT's), :func:`appearance_similarity` and :func:`mahalanobis_gate`;
one's own are functions at module level, saved by name like these.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import box_coding, encode_boxes, iou_matrix
from pgm.core.frame import FrameContext
from pgm.factors.association import AssignedDetectionLikelihood

from .rules import find_rule

__all__ = ["AssociationInputs", "PieceValues", "iou_affinity", "momentum",
           "appearance_similarity", "direction_consistency", "mahalanobis_distances",
           "mahalanobis_gate"]


@dataclass(frozen=True)
class AssociationInputs:
    """What an association piece reads: ``fn(inputs, **args) -> (K, M)``.

    ``pred`` ``(K, 4)``: the replicas' predicted boxes (cx, cy, w, h); ``boxes`` ``(M, 4)``
    (cx, cy, w, h) and ``scores`` ``(M,)`` (mapped): the detections. What the factor's
    pieces need besides (None otherwise): ``last`` ``(K, 4)``: each replica's last
    detection (a round against it, or pieces of one's own); ``velocity`` ``(K, 2)``,
    ``known`` ``(K,)`` and ``reference`` ``(K, 4)``: its unit direction of motion
    ``(dy, dx)``, whether it has one, and its observation ``delta_t`` frames back
    (:func:`momentum`); ``appearance`` ``(K, M)``: the similarity of its appearance
    model with each detection (:func:`appearance_similarity`; None in a frame without an
    image). With pieces of one's own: ``mean`` ``(K, d)`` and ``cov`` ``(K, d, d)``: the
    replicas' state beliefs' moments (the belief protocol: a Kalman replica's, or the
    particles' weighted ones); ``labels``: the state's component names; ``variable``;
    ``graph``: the factors (e.g. the detection likelihood's ``H`` and ``noise_cov``);
    ``frame``."""

    pred: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    last: np.ndarray | None = None
    velocity: np.ndarray | None = None
    known: np.ndarray | None = None
    reference: np.ndarray | None = None
    appearance: np.ndarray | None = None
    mean: np.ndarray | None = None
    cov: np.ndarray | None = None
    labels: tuple[str, ...] = ()
    variable: str = ""
    graph: Any = None
    frame: FrameContext | None = None


class PieceValues:
    """The pieces' values ``(K, M)`` on one frame's :class:`AssociationInputs`, each
    computed once (a round's affinity, terms and gates, found by name as rules are)."""

    def __init__(self, inputs: AssociationInputs, owner: str = "association"):
        self.inputs = inputs
        self.owner = owner
        self.shape = (len(inputs.pred), len(inputs.boxes))
        self._cache: dict[tuple, np.ndarray] = {}

    @staticmethod
    def _key(item: dict[str, Any]) -> tuple:
        return item["fn"], repr(sorted(item["args"].items()))

    def __call__(self, item: dict[str, Any], what: str) -> np.ndarray:
        key = self._key(item)
        got = self._cache.get(key)
        if got is None:
            fn, _ = find_rule(item["fn"], f"{self.owner}: association {what}")
            got = np.asarray(fn(self.inputs, **item["args"]))
            if got.shape != self.shape:
                raise ValueError(f"{self.owner}: association {what} {item['fn']!r} returned "
                                 f"shape {got.shape}, expected {self.shape}")
            self._cache[key] = got
        return got

    def seed(self, item: dict[str, Any], value: np.ndarray) -> None:
        """Give a piece's value already computed (the plain IoU)."""
        self._cache[self._key(item)] = value


def iou_affinity(inputs: AssociationInputs, against: str = "prediction", buffer: float = 0.0,
                 fuse_score: bool = False) -> np.ndarray:
    """``(K, M)`` IoU of each replica's box — its prediction, or its ``last`` detection
    (``against="last"``: OC-SORT's recovery) — with each detection's; of both boxes
    enlarged about their centres to ``(1 + 2 buffer)`` times their size (C-BIoU); times
    the detection's score with ``fuse_score`` (BoT-SORT)."""
    if against not in ("prediction", "last"):
        raise ValueError(f"iou_affinity: against is 'prediction' or 'last', got {against!r}")
    if against == "last" and inputs.last is None:
        raise ValueError("a round against the last observations needs them")
    mine = inputs.last if against == "last" else inputs.pred
    if buffer:
        grow = np.array([1.0, 1.0, 1.0 + 2.0 * buffer, 1.0 + 2.0 * buffer])
        out = iou_matrix(mine * grow, inputs.boxes * grow)
    else:
        out = iou_matrix(mine, inputs.boxes)
    if fuse_score:
        out = out * inputs.scores[None, :]
    return out


def direction_consistency(velocity: np.ndarray, known: np.ndarray, reference: np.ndarray,
                          boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """OC-SORT's momentum term ``(K, M)``: for replica ``k`` moving in the unit direction
    ``velocity[k]`` (``(dy, dx)``; ``known[k]`` false: no direction yet, term 0) and
    detection ``j``, ``(π/2 − |angle|)/π`` between that direction and the one from the
    replica's ``reference`` box (its observation ``delta_t`` frames back) to the
    detection, times the detection's score (in float32, as the ``trackers`` package)."""
    d = boxes[None, :, :2] - reference[:, None, :2]
    norm = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2) + 1e-6
    dx, dy = d[..., 0] / norm, d[..., 1] / norm
    cos = np.clip(velocity[:, 1:2] * dx + velocity[:, 0:1] * dy, -1.0, 1.0)
    cost = (np.pi / 2.0 - np.abs(np.arccos(cos))) / np.pi
    cost = (known[:, None] * cost).astype(np.float32)
    cost *= scores[None, :]
    return cost


def momentum(inputs: AssociationInputs) -> np.ndarray:
    """OC-SORT's momentum term (:func:`direction_consistency` of the replicas' directions
    of motion, ``inputs.velocity``, from their ``reference`` observations)."""
    if inputs.velocity is None:
        raise ValueError("the momentum term needs the replicas' directions of motion "
                         "(an association that keeps observations)")
    return direction_consistency(inputs.velocity, inputs.known, inputs.reference,
                                 inputs.boxes, inputs.scores)


def appearance_similarity(inputs: AssociationInputs) -> np.ndarray:
    """``(K, M)`` similarity of each replica's appearance model with each detection
    (``exp(log-likelihood / λ)`` multiplied over the association's appearance factors; 0
    for a replica without a model yet, and everywhere in a frame without an image)."""
    if inputs.appearance is None:
        return np.zeros((len(inputs.pred), len(inputs.boxes)))
    return inputs.appearance


def mahalanobis_distances(inputs: AssociationInputs) -> np.ndarray:
    """``(K, M)`` squared Mahalanobis distances of the detections from each replica's
    predicted measurement: the detection encoded as the state's box (its first four
    columns), against ``H m`` with covariance ``H P Hᵀ + R`` (``H`` and ``R`` of the
    graph's :class:`~pgm.factors.association.AssignedDetectionLikelihood` on the
    variable; ``H`` the first four columns and no ``R`` without one)."""
    coding = box_coding(inputs.labels)
    z = encode_boxes(inputs.boxes, coding)  # (M, 4)
    liks = [f for f in inputs.graph.factors_of(inputs.variable, "likelihood")
            if isinstance(f, AssignedDetectionLikelihood)]
    d = inputs.mean.shape[1]
    H = liks[0].H if liks else np.eye(4, d)  # noqa: N806
    R = liks[0].noise_cov(inputs.mean) if liks else np.zeros((len(inputs.mean), 4, 4))  # noqa: N806
    R = np.broadcast_to(R, (len(inputs.mean),) + H.shape[:1] * 2)  # noqa: N806
    S = np.einsum("ij,kjl,ml->kim", H, inputs.cov, H) + R  # noqa: N806
    nu = z[None, :, :] - (inputs.mean @ H.T)[:, None, :]  # (K, M, 4)
    return np.einsum("kmi,kij,kmj->km", nu, np.linalg.inv(S), nu)


def mahalanobis_gate(inputs: AssociationInputs, quantile: float = 0.99) -> np.ndarray:
    """Pairs whose squared Mahalanobis distance (:func:`mahalanobis_distances`) is within
    the ``quantile`` of the chi-square distribution of the measurement's dimension — the
    gate of a Kalman tracker on its predicted covariance (e.g. DeepSORT's 0.95)."""
    from scipy.stats import chi2

    d2 = mahalanobis_distances(inputs)
    return d2 <= chi2.ppf(quantile, df=4)
