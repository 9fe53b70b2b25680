"""Tracking by detection as factors: a box state with exact Kalman rules, and data association.

The classic trackers (SORT, ByteTrack) are a plate of per-target linear-Gaussian box
states whose measurement is *the detection assigned to the target*. Declared as a
factor graph of the one engine (:mod:`pgm.models.sort`), one target is

* a ``state`` variable whose first four columns code its box (:data:`pgm.core.boxes.
  BOX_CODINGS`: the corners ``x1, y1, x2, y2`` of the ``trackers`` package, or the SORT
  paper's centre, area and aspect ``cx, cy, s, r``) followed by their rates;
* :class:`BoxPrior` — a Gaussian prior centred on the birth detection, rates zero;
* a :class:`~pgm.factors.LinearGaussianTransition` (constant velocity);
* :class:`DetectionAssociation` (kind ``"association"``) — the data-association node
  between the replicas and the frame's detections: Hungarian assignment on IoU in one or
  more *rounds* (SORT: one; ByteTrack: high-score detections first, then the
  low-score ones against the replicas left over), each with its IoU gate; the engine
  runs it at its ``assign`` stage, after predict and before the likelihoods;
* :class:`AssignedDetectionLikelihood` — ``z = H x + N(0, R)`` with ``z`` the coded box of
  the detection assigned to this replica (no assignment: no evidence), updated by the
  exact Kalman rule of :mod:`pgm.inference.association`, for all replicas in a few
  batched matrix products.

The track layer (confirmation, coasting, the lost stage, births from the detections
no replica took) is the plate's :class:`~pgm.core.plate.Lifecycle`, as for every plate;
with an association factor it reads the assignment of the ``assign`` stage instead of
matching again.

>>> f = DetectionAssociation("box", rounds=[{"iou": 0.3}])
>>> f.rounds[0]["min_score"], f.rounds[0]["iou"]
(-inf, 0.3)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgm.core.boxes import (
    BOX_CODINGS,
    box_code_columns,
    decode_boxes,
    encode_boxes,
)
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param
from pgm.core.variable import Variable
from pgm.factors.detection_association import (
    APPEARANCE,
    IOU_AFFINITY,
    MOMENTUM,
    TRACK_POOLS,
    DetectionAssociation,
    RoundPlan,
    require_box_coding,
)
from pgm.factors.gaussian import GaussianPrior, LinearGaussianTransition, _as_cov
from pgm.factors.kinds import LikelihoodFactor
from pgm.factors.scores import LEARNED_SCORE_MAPS, SCORE_MAPS, map_scores

__all__ = ["BoxPrior", "BoxTransition", "DetectionAssociation", "AssignedDetectionLikelihood",
           "SCORE_MAPS", "LEARNED_SCORE_MAPS", "TRACK_POOLS", "map_scores", "constant_velocity",
           "axis_sizes", "X_LABELS", "CAMERA_WARPS", "CAMERA_ORDERS", "RoundPlan",
           "IOU_AFFINITY", "MOMENTUM", "APPEARANCE"]

#: the box labels read along the image's x axis (their noise scales with the box's width);
#: the others of a box state along y (height)
X_LABELS = frozenset({"x1", "x2", "cx", "w", "vx1", "vx2", "vcx", "vw"})


def axis_sizes(labels, coding: str, x: np.ndarray) -> np.ndarray:
    """``(..., d)``: for each state component of ``x`` ``(..., d)`` the size of its box
    along the component's axis (width for ``x1, x2, cx, w`` and their rates, height for
    the rest): what scale-aware noise is in units of."""
    if coding == "xysr":
        raise ValueError("scale-aware noise needs a box state of corners (xyxy) or centre and "
                         "size (cxcywh), not area and aspect (xysr)")
    cols = box_code_columns(tuple(labels))[1]
    box = decode_boxes(x[..., cols], coding)
    w, h = np.abs(box[..., 2:3]), np.abs(box[..., 3:4])
    is_x = np.array([lab in X_LABELS for lab in labels])
    return np.where(is_x, w, h)


def _relative_std(factor: Factor, value, n: int) -> np.ndarray | None:
    """A factor's ``relative_std``: ``n`` positive finite stds, or None."""
    if value is None:
        return None
    r = np.asarray(value, dtype=float).reshape(-1)
    check_finite_param(f"{factor.name}.relative_std", r, positive=True)
    if r.size != n:
        raise ValueError(f"factor {factor.name!r}: relative_std needs {n} values, got {r.size}")
    return r


def constant_velocity(coding: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Labels, transition ``F`` and measurement ``H`` of a constant-velocity box state in
    ``coding``: the four box columns and a rate for each (``xysr``: none for the aspect
    ``r``, which SORT holds constant)."""
    box = list(BOX_CODINGS[coding])
    moving = box[:3] if coding == "xysr" else box
    labels = box + [f"v{c}" for c in moving]
    d = len(labels)
    F = np.eye(d)
    for i in range(len(moving)):
        F[i, 4 + i] = 1.0
    H = np.eye(4, d)
    return labels, F, H


class _RelativeStd:
    """A factor with an optional ``relative_std`` (scale-aware noise), saved with it."""

    relative_std: np.ndarray | None = None

    def params(self) -> dict[str, Any]:
        p = super().params()
        if self.relative_std is not None:
            p["relative_std"] = self.relative_std
        return p


class BoxPrior(_RelativeStd, GaussianPrior):
    """A Gaussian prior on a box state (any :data:`~pgm.core.boxes.BOX_CODINGS`), re-centred
    on each new target's detection box with its rates set to zero. Its covariance is
    ``cov`` (the initial uncertainty ``P0``) or, with ``relative_std`` (one std per state
    component, in units of the box's width or height along the component's axis,
    :func:`axis_sizes`), ``diag((relative_std · size)²)`` of each new target's box (the
    scale-aware ``P0`` of BoT-SORT).
    """

    def __init__(self, variable: str, *, mean, cov=0.0, relative_std=None,
                 name: str | None = None):
        super().__init__(variable, mean=mean, cov=cov, name=name)
        self.relative_std = _relative_std(self, relative_std, self.mean_.size)

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        coding = require_box_coding(self, variables, self.variables[0])
        if self.relative_std is not None:
            axis_sizes(variables[self.variables[0]].labels, coding, self.mean_)

    def born_at(self, values: dict[str, float], labels) -> BoxPrior:
        coding, cols = box_code_columns(tuple(labels or ()))
        try:
            box = np.array([values["cx"], values["cy"], values["w"], values["h"]], dtype=float)
        except KeyError:
            box = None
        if coding is None or box is None:
            raise ValueError(f"prior {self.name!r}: needs a box (cx, cy, w, h) and a box state, "
                             f"got {sorted(values)} for labels {labels}")
        mean = np.zeros(self.mean_.shape)
        if coding == "xyxy":  # inline: a plate's births call this once per new target
            cx, cy, hw, hh = box[0], box[1], box[2] / 2.0, box[3] / 2.0
            mean[cols] = (cx - hw, cy - hh, cx + hw, cy + hh)
        else:
            mean[cols] = encode_boxes(box, coding)
        new = self._with_mean(mean)
        if self.relative_std is not None:
            new.cov = np.diag((self.relative_std * axis_sizes(labels, coding, mean)) ** 2)
        return new


class AssignedDetectionLikelihood(LikelihoodFactor):
    """``z = H x + N(0, R)`` where ``z`` is the coded box (the state's coding) of the
    detection the ``assign`` stage gave this replica; a replica without one has no
    evidence in the frame. Exact Kalman rules (and the VB adaptive-noise rule) in
    :mod:`pgm.inference.association`.

    ``relative_std`` (one per measured component): ``R = diag((relative_std · size)²)``
    with ``size`` the predicted box's width or height along each component's axis
    (:func:`axis_sizes`) — scale-aware measurement noise, as BoT-SORT's; ``R`` is then
    unused. ``reupdate``: OC-SORT's observation-centric re-update — a replica matched
    again after frames without a detection is first re-filtered along a straight line of
    virtual detections from its last one to this one, so that the drift of the
    prediction through the gap does not stay in its velocity. ``occlusion_gate`` (σ, a
    corner state only): the part-graph idea of Zhang and Kang (2015) on a box — a box is made of its
    edges, and a detection of a half-hidden person sees only some of them: an edge of the
    detection that lies *inside* the predicted box by more than ``occlusion_gate``
    innovation standard deviations is taken as hidden (its row carries no information),
    so the target's box keeps its predicted extent there and is updated by the edges
    that are seen.
    """

    def __init__(self, variable: str, *, H, R, relative_std=None, reupdate: bool = False,
                 occlusion_gate: float | None = None, name: str | None = None):
        super().__init__(variable, name=name)
        self.reupdate = bool(reupdate)
        self.occlusion_gate = None if occlusion_gate is None else float(check_finite_param(
            f"{self.name}.occlusion_gate", occlusion_gate, positive=True))
        self.H = np.atleast_2d(np.asarray(H, dtype=float))
        check_finite_param(f"{self.name}.H", self.H)
        self.R = _as_cov(R, self.H.shape[0], f"{self.name}.R")
        if np.any(np.linalg.eigvalsh(self.R) <= 0):
            raise ValueError(f"factor {self.name!r}: R must be positive definite")
        k, d = self.H.shape
        #: whether ``H = [I 0]`` reads the box columns (the Kalman rule then slices)
        self.selects = d >= k and bool(np.array_equal(self.H, np.eye(k, d)))
        self.relative_std = _relative_std(self, relative_std, k)
        if self.relative_std is not None and not self.selects:
            raise ValueError(f"factor {self.name!r}: relative_std needs H = [I 0]")
        self._labels: tuple | None = None
        self._coding: str | None = None

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"H": self.H, "R": self.R}
        if self.relative_std is not None:
            p["relative_std"] = self.relative_std
        if self.reupdate:
            p["reupdate"] = True
        if self.occlusion_gate is not None:
            p["occlusion_gate"] = self.occlusion_gate
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.H.shape[1], "H's column count")
        if self.H.shape[0] != 4:
            raise ValueError(f"factor {self.name!r}: H must map the state to a box (4 rows), "
                             f"got {self.H.shape}")
        self._coding = require_box_coding(self, variables, self.variables[0])
        self._labels = tuple(variables[self.variables[0]].labels)
        if self.relative_std is not None:
            axis_sizes(self._labels, self._coding, np.ones(self.H.shape[1]))
        if self.occlusion_gate is not None and (self._coding != "xyxy" or not self.selects):
            raise ValueError(f"factor {self.name!r}: occlusion_gate needs a corner state "
                             f"(x1, y1, x2, y2 first) read by H = [I 0]")

    def scales(self, mean: np.ndarray) -> np.ndarray | None:
        """``(B, k)`` the size each measured component's noise is in units of, at the
        states ``mean`` ``(B, d)`` (None: fixed noise)."""
        if self.relative_std is None:
            return None
        return axis_sizes(self._labels, self._coding, mean)[:, :self.H.shape[0]]

    def noise_cov(self, mean: np.ndarray) -> np.ndarray:
        """``R`` for each state of ``mean`` ``(B, d)``: ``(k, k)`` fixed, or ``(B, k, k)``."""
        sizes = self.scales(mean)
        if sizes is None:
            return self.R
        k = self.H.shape[0]
        return np.einsum("bk,kl->bkl", (self.relative_std * sizes) ** 2, np.eye(k))

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        raise ValueError(f"factor {self.name!r}: the assigned detection exists only in a plate "
                         f"with a DetectionAssociation (its rules read the frame's assignment)")


#: what of a box state the camera's image motion moves (:class:`BoxTransition`)
CAMERA_WARPS = ("box", "centre", "none")
#: where the camera's image motion enters a predict (:class:`BoxTransition`)
CAMERA_ORDERS = ("before", "after")


class BoxTransition(_RelativeStd, LinearGaussianTransition):
    """Constant-velocity box dynamics ``x_t = F x_{t-1} + N(0, Q)`` whose noise is fixed
    (``Q``) or, with ``relative_std`` (one std per state component), scale-aware:
    ``Q = diag((relative_std · size)²)`` with ``size`` the box's width or height along
    each component's axis at ``x_{t-1}`` (:func:`axis_sizes`; BoT-SORT's process noise).

    When a frame carries the camera's image motion ``[M | t]``, ``camera`` says what it
    moves (:func:`pgm.core.motion.linear_state_warp`): ``"box"`` (default) the whole box
    — corners or centre through ``M p + t``, sizes scaled by ``sqrt|det M|``; ``"centre"``
    the box's centre and its rate only, its width and height unchanged (BoT-SORT's camera
    motion compensation); ``"none"`` nothing (a tracker without compensation, C-BIoU).
    ``camera_order`` says when: ``"before"`` the predict (``x_t = F (T x_{t-1} + c) +
    w``: the process noise is added in the new frame's image) or ``"after"`` it (``x_t =
    T (F x_{t-1} + w) + c``: the noise is carried through the motion, ``P ← T (F P Fᵀ +
    Q) Tᵀ``, as BoT-SORT applies it). The means agree; the covariances differ by ``Q``
    against ``T Q Tᵀ``.
    """

    def __init__(self, variable: str, *, F, Q, relative_std=None, camera: str = "box",
                 camera_order: str = "before", name: str | None = None):
        super().__init__(variable, F=F, Q=Q, name=name)
        self.relative_std = _relative_std(self, relative_std, self.F.shape[0])
        if camera not in CAMERA_WARPS:
            raise ValueError(f"factor {self.name!r}: camera must be one of {CAMERA_WARPS}, got "
                             f"{camera!r}")
        if camera_order not in CAMERA_ORDERS:
            raise ValueError(f"factor {self.name!r}: camera_order must be one of "
                             f"{CAMERA_ORDERS}, got {camera_order!r}")
        self.camera, self.camera_order = camera, camera_order
        self._labels: tuple | None = None
        self._coding: str | None = None

    def params(self) -> dict[str, Any]:
        p = super().params()
        if self.camera != "box":
            p["camera"] = self.camera
        if self.camera_order != "before":
            p["camera_order"] = self.camera_order
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        self._coding = require_box_coding(self, variables, self.variables[0])
        self._labels = tuple(variables[self.variables[0]].labels)
        if self.relative_std is not None:
            axis_sizes(self._labels, self._coding, np.ones(self.F.shape[0]))

    def noise_cov(self, mean: np.ndarray) -> np.ndarray:
        """``Q`` at the states ``mean`` ``(B, d)``: ``(d, d)`` fixed, or ``(B, d, d)``."""
        if self.relative_std is None:
            return self.Q
        sizes = axis_sizes(self._labels, self._coding, mean)
        return np.einsum("bk,kl->bkl", (self.relative_std * sizes) ** 2,
                         np.eye(self.F.shape[0]))

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        if self.relative_std is None:
            return super().sample(rng, *past)
        x = past[0]
        sd = self.relative_std * axis_sizes(self._labels, self._coding, x)
        return x @ self.F.T + sd * rng.standard_normal(x.shape)
