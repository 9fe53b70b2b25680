"""The base of the box appearance likelihoods: the first-frame model protocol, box
indices, the adapt rate, and the bounds of the sizes a cue takes
(:mod:`pgm.observation.appearance.likelihoods`)."""

from __future__ import annotations

import functools
from abc import abstractmethod
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, ClassVar

import cv2
import numpy as np

from pgm.core.frame import FrameContext
from pgm.core.learned import LearnedState
from pgm.core.numerics import check_finite_param
from pgm.core.resolution import working_frames
from pgm.core.variable import Variable
from pgm.factors import LikelihoodFactor

__all__ = ["BoxAppearanceLikelihood", "FeatureDotCue", "SIZE_BOUNDS", "TemplateState",
           "bounded_int", "grey_frame"]


#: bounds of the sizes an appearance cue takes (bins, cells, rings, samples, ...): a
#: size is work and memory per particle and frame, so ``gradient(n_orient=1e6)`` is
#: refused when the factor is built, naming the option, not met as an out-of-memory
SIZE_BOUNDS = {"n_orient": (2, 36), "cells": (1, 16), "grid": (1, 64), "rings": (1, 64),
               "angles": (1, 360), "radial_samples": (1, 16), "n_components": (1, 64),
               "n_samples": (1, 65536), "n_h": (1, 180), "n_s": (1, 256), "n_v": (1, 256),
               "scales": (1, 15), "windows": (1, 4), "n_scales": (3, 65)}


def bounded_int(factor: str, name: str, value: Any) -> int:
    """``value`` as an integer within :data:`SIZE_BOUNDS` ``[name]``; anything else (a
    fraction, NaN, infinity, out of bounds) is a ``ValueError`` naming the factor and
    the parameter."""
    low, high = SIZE_BOUNDS[name]
    try:
        v = float(value)
        ok = np.isfinite(v) and v == int(v) and low <= v <= high
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise ValueError(f"factor {factor!r}: {name} must be an integer from {low} to "
                         f"{high}, got {value!r}")
    return int(v)


def _bins(factor: str, n_h: Any, n_s: Any, n_v: Any) -> tuple[int, int, int | None]:
    """Colour bin counts ``n_h, n_s, n_v`` (``n_v`` may be None: the layout's own)."""
    return (bounded_int(factor, "n_h", n_h), bounded_int(factor, "n_s", n_s),
            None if n_v is None else bounded_int(factor, "n_v", n_v))


def _bounded_pair(factor: str, name: str, value: Any) -> tuple[int, int]:
    """A pair of :func:`bounded_int` (``cells``, ``grid``)."""
    try:
        a, b = value
    except (TypeError, ValueError):
        raise ValueError(f"factor {factor!r}: {name} must be two integers, got "
                         f"{value!r}") from None
    return bounded_int(factor, name, a), bounded_int(factor, name, b)


@dataclass
class TemplateState(LearnedState):
    """What a cue with one template learns: the template (None until given or learned
    in the first frame)."""

    template: Any = None


@functools.cache
def _state_field_names(cls: type) -> frozenset[str]:
    """The names of a factor class's learned-state fields (set as it learns: they never
    change how a box is read)."""
    state = getattr(cls, "State", None)
    return frozenset(f.name for f in fields(state)) if state is not None \
        and is_dataclass(state) else frozenset()


class BoxAppearanceLikelihood(LikelihoodFactor):
    """Base of the appearance factors: a box ``(cx, cy, w, h)`` inside a variable's state
    scored against an appearance model learned in the first frame.

    It holds what every appearance cue shares: ``lam`` (the likelihood's sharpness),
    ``box_indices`` (where ``cx, cy, w, h`` sit in the state), :meth:`boxes`, the check
    that the indices fit the variable, ``adapt_rate`` (in [0, 1]; the factor learns
    after each frame only when it is positive) and the first-frame protocol:
    :meth:`initialize` calls the subclass's :meth:`learn` at the prior mean unless the
    model (the attribute named by ``model_attr``) was given, and :meth:`require_model`
    refuses to score without one.
    """

    abstract = True
    #: the attribute holding the appearance model (None until given or learned)
    model_attr: ClassVar[str] = "template"
    #: what it learns (a subclass with another model declares its own)
    State = TemplateState

    def __init__(self, variable: str, *, lam: float, box_indices=(0, 1, 2, 3),
                 adapt_rate: float = 0.0, name: str | None = None):
        super().__init__(variable, name=name)
        self.lam = float(check_finite_param(f"{self.name}.lam", lam, positive=True))
        self.box_indices = tuple(int(i) for i in box_indices)
        if len(self.box_indices) != 4:
            raise ValueError(f"factor {self.name!r}: box_indices must have 4 entries")
        self.adapt_rate = float(check_finite_param(f"{self.name}.adapt_rate", adapt_rate,
                                                   nonneg=True))
        if self.adapt_rate > 1:
            raise ValueError(f"factor {self.name!r}: adapt_rate must be in [0, 1]")

    @property
    def learns(self) -> bool:
        """Whether :meth:`update` runs after each frame (``adapt_rate > 0``)."""
        return self.adapt_rate > 0

    @property
    def has_model(self) -> bool:
        """Whether the appearance model is there (given, or learned in the first frame)."""
        return getattr(self, self.model_attr, None) is not None

    def require_model(self) -> None:
        """Raise a ``ValueError`` naming the factor when there is no model to score with."""
        if not self.has_model:
            raise ValueError(f"factor {self.name!r} has no {self.model_attr}: give one or run "
                             f"it from the first frame")

    def check(self, variables: dict[str, Variable]) -> None:
        dim = variables[self.variables[0]].dim
        if max(self.box_indices) >= dim:
            raise ValueError(f"factor {self.name!r}: box_indices {self.box_indices} do not fit "
                             f"variable {self.variables[0]!r} of dim {dim}")

    def boxes(self, x: np.ndarray) -> np.ndarray:
        """Boxes ``(N, 4)`` ``(cx, cy, w, h)`` of particles ``x``."""
        i = self.box_indices
        if i == (i[0], i[0] + 1, i[0] + 2, i[0] + 3):
            return x[:, i[0]:i[0] + 4]  # a view: no copy on the hot path
        return x[:, list(i)]

    def initialize(self, ctx: FrameContext, value: np.ndarray) -> None:
        """Learn the model from the first frame at the state ``value`` (unless given)."""
        if not self.has_model:
            self.learn(ctx, np.asarray(value, dtype=float))

    def _cached(self, ctx: FrameContext, key: tuple, make):
        """``make()`` once per frame for this factor. The entry holds the factor itself,
        so its ``id`` (in the key) cannot be reused by another factor while the frame's
        cache lives (a frame may be stepped by several engines in turn)."""
        return ctx.cached((id(self),) + key, lambda: (self, make()))[1]

    #: parameters that set how the model scores, not how a box is read
    _NOT_READING = frozenset({"lam", "adapt_rate", "adapt_threshold"})

    def reading_key(self) -> tuple:
        """What reading a box depends on: the class and its parameters less the model and
        the likelihood's sharpness (models with equal keys read boxes alike, so one pass
        over the boxes serves them all). Computed once and kept until an attribute that
        may change it is set (it is asked for every track on every frame)."""
        key = self.__dict__.get("_reading_key")
        if key is None:
            key = (type(self).__name__,) + tuple(
                (k, repr(v)) for k, v in sorted(self.params().items())
                if k != self.model_attr and k not in self._NOT_READING)
            self.__dict__["_reading_key"] = key
        return key

    def __setattr__(self, name: str, value: Any) -> None:
        if name not in self._NOT_READING and name != self.model_attr and \
                name not in _state_field_names(type(self)):
            self.__dict__.pop("_reading_key", None)  # a parameter changed: read it afresh
        super().__setattr__(name, value)

    @classmethod
    def read_alike(cls, models) -> bool:
        """Whether ``models`` all read boxes as the first does (:meth:`reading_key`)."""
        key = models[0].reading_key()
        return all(m.reading_key() == key for m in models[1:])

    @abstractmethod
    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """Set the appearance model from frame ``ctx`` at the state ``value`` ``(d,)``."""


def grey_frame(ctx: FrameContext) -> np.ndarray:
    """The frame as ``float32`` grey levels, computed once per frame (cached)."""
    def make():
        img = ctx.image
        if img is None:
            raise ValueError(f"frame {ctx.index} has no image")
        grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        return np.ascontiguousarray(grey, dtype=np.float32)

    return ctx.cached(("grey-f32",), make)


class FeatureDotCue:
    """Mixin of the cues scored as ``log p(z | X) = -λ (1 - f(X) · t)``: a feature vector
    ``f`` of the box (the class's ``feature_method``, ``(N, D)``) against a template ``t``
    that is ``f`` of the first box. Many models of such a cue are scored against many
    boxes, and learn from boxes, with one feature pass over the boxes per level
    (:func:`pgm.core.resolution.appearance_matrix`, :func:`~pgm.core.resolution.learn_all`),
    each level's frame halved by averaging, the boxes ``(cx, cy, w, h)`` given as the
    states (``box_indices`` (0, 1, 2, 3)). Models that read boxes otherwise (another
    :meth:`BoxAppearanceLikelihood.reading_key`) are asked one by one on the same frames."""

    #: the method ``(x, ctx) -> (N, D)`` giving the features
    feature_method: ClassVar[str] = ""

    @classmethod
    def log_likelihood_matrix(cls, models, x, ctx, levels=None) -> np.ndarray:
        """``(K, M)`` log-likelihoods of the boxes ``x`` under ``K`` models, box ``j`` read
        on the frame halved ``levels[j]`` times (None: the frame itself)."""
        x = np.asarray(x, dtype=float).reshape(-1, 4)
        lv = np.zeros(len(x), dtype=np.intp) if levels is None else np.asarray(levels)
        out = np.zeros((len(models), len(x)))
        shared = cls.read_alike(models)
        if shared:
            for m in models:
                m.require_model()
            templates = np.array([m.template for m in models], dtype=float)
            lam = np.array([m.lam for m in models], dtype=float)[:, None]
        for frame, idx, xb in working_frames(ctx, x, lv):
            if shared:
                f = np.asarray(getattr(models[0], cls.feature_method)(xb, frame), dtype=float)
                out[:, idx] = -lam * (1.0 - templates @ f.T)
            else:
                for i, m in enumerate(models):
                    out[i, idx] = m.log_likelihood(xb, frame)
        return out

    @classmethod
    def learn_many(cls, models, ctx, values, levels=None) -> None:
        """Each model's template from its own box in ``values`` ``(K, 4)``, read as
        :meth:`log_likelihood_matrix` reads it, the features computed in one pass per
        level."""
        values = np.asarray(values, dtype=float).reshape(len(models), 4)
        lv = np.zeros(len(values), dtype=np.intp) if levels is None else np.asarray(levels)
        shared = cls.read_alike(models)
        for frame, idx, xb in working_frames(ctx, values, lv):
            if shared:
                f = np.asarray(getattr(models[0], cls.feature_method)(xb, frame), dtype=float)
                for i, row in zip(idx, f, strict=True):
                    models[i].template = row.copy()
            else:
                for i, v in zip(idx, xb, strict=True):
                    models[i].learn(frame, v)
