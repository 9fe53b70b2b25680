"""The association's extension points: terms and gates of one's own
(:class:`~pgm.factors.association.DetectionAssociation`'s ``terms`` and ``gates``), what
they read (:class:`AssociationInputs`), and the Mahalanobis gate of a Kalman tracker on
its predicted covariance.

A *term* ``f(inputs, **args) -> (K, M)`` adds ``weight × f`` to what every round of the
association maximises; a *gate* ``g(inputs, **args) -> (K, M)`` allows only the pairs
where it is true. Both are functions at module level, saved by name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import box_coding, encode_boxes
from pgm.core.frame import FrameContext
from pgm.factors.association import AssignedDetectionLikelihood

from .context import RuleContext
from .rules import find_rule

__all__ = ["AssociationInputs", "mahalanobis_distances", "mahalanobis_gate"]


@dataclass(frozen=True)
class AssociationInputs:
    """What an association term or gate reads: ``fn(inputs, **args) -> (K, M)``.

    ``pred`` ``(K, 4)``: the replicas' predicted boxes (cx, cy, w, h); ``mean`` ``(K, d)``
    and ``cov`` ``(K, d, d)``: their state beliefs' moments (the belief protocol: a Kalman
    replica's, or the particles' weighted ones); ``boxes`` ``(M, 4)`` (cx, cy, w, h) and
    ``scores`` ``(M,)`` (mapped): the detections; ``labels``: the state's component names;
    ``graph``: the factors (e.g. the detection likelihood's ``H`` and ``noise_cov``)."""

    pred: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    labels: tuple[str, ...]
    variable: str
    graph: Any
    frame: FrameContext


def _extensions(ctx: RuleContext, factor, frame: FrameContext, pred: np.ndarray,
                boxes: np.ndarray, scores: np.ndarray) -> dict[str, Any]:
    """The factor's terms summed (``extra``) and gates joined (``allowed``), and each
    round's own on top (``per_round``: one ``(extra, allowed)`` per round, None where a
    round adds nothing)."""
    var = factor.variables[0]
    b = ctx.beliefs[var]
    inputs = AssociationInputs(pred, b.mean(), b.cov(), boxes, np.asarray(scores, float),
                               tuple(ctx.graph.variables[var].labels), var, ctx.graph, frame)
    shape = (len(pred), len(boxes))

    def call(item: dict[str, Any], what: str) -> np.ndarray:
        fn, _ = find_rule(item["fn"], f"factor {factor.name!r}: association {what}")
        got = np.asarray(fn(inputs, **item["args"]))
        if got.shape != shape:
            raise ValueError(f"factor {factor.name!r}: association {what} {item['fn']!r} "
                             f"returned shape {got.shape}, expected {shape}")
        return got

    def combine(terms, gates, extra=None, allowed=None):
        for t in terms:
            add = t["weight"] * call(t, "term").astype(float)
            extra = add if extra is None else extra + add
        for g in gates:
            ok = call(g, "gate").astype(bool)
            allowed = ok if allowed is None else allowed & ok
        return extra, allowed

    extra, allowed = combine(factor.terms, factor.gates)
    out: dict[str, Any] = {}
    if any(r["terms"] or r["gates"] for r in factor.rounds):
        out["per_round"] = [combine(r["terms"], r["gates"], extra, allowed)
                            for r in factor.rounds]
    else:
        if extra is not None:
            out["extra"] = extra
        if allowed is not None:
            out["allowed"] = allowed
    return out


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
