"""Appearance likelihood factors (image evidence for box-valued variables).

:class:`ColourHistogramLikelihood` — Pérez et al. (2002), SPEC §1: the colour
histogram of the candidate box against a template histogram ``q``, through the
Bhattacharyya coefficient ``ρ``:

.. math::
    \\log p(z \\mid X) = -\\lambda\\,(1 - \\rho(X)) + \\mathrm{const}

All particles of a frame are scored in one vectorised pass
(:mod:`pgm.appearance.colour`); the colour quantisation is cached on the frame and
shared with every other factor using the same bin layout.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..factors import LikelihoodFactor
from ..frame import FrameContext
from ..numerics import check_finite_param
from ..variable import Variable
from .colour import ColourHistogramScorer

__all__ = ["ColourHistogramLikelihood", "FragmentsLikelihood", "GradientLikelihood"]


class ColourHistogramLikelihood(LikelihoodFactor):
    """Colour-histogram likelihood of a box variable ``(cx, cy, w, h, ...)``.

    Parameters
    ----------
    variable : str
        A variable whose components ``box_indices`` are ``(cx, cy, w, h)``.
    lam : float
        ``λ`` (default 20, Pérez et al.; seed 002's garbled setting reads as 2.5).
    layout : {"perez", "hsv", "rgb"}
        Bin layout (SPEC §1): ``"perez"`` keeps a value-only histogram for
        low-saturation pixels, so greyscale video works.
    n_h, n_s, n_v : int
        Bin counts of the layout (``n_v=None``: 16 value bins for ``"perez"``, 4 for
        ``"hsv"``).
    kernel : {"uniform", "epanechnikov"}
        Pixel weighting inside the box.
    template : array_like, shape (B,), optional
        The reference histogram ``q``; when omitted it is learned from the first frame
        at the prior mean (:meth:`initialize`).
    box_indices : tuple of 4 int
        Where ``cx, cy, w, h`` sit in the variable's state.
    adapt_rate : float
        Adaptive template (Nummiaro et al. 2003), off at 0 (the default): after a frame
        whose score at the estimate has ``ρ ≥ adapt_threshold``, the template becomes
        ``(1 − adapt_rate) q + adapt_rate p(estimate)``.
    adapt_threshold : float
        ``π_T``: the Bhattacharyya coefficient required to adapt.
    """

    def __init__(self, variable: str, *, lam: float = 20.0, layout: str = "perez",
                 n_h: int = 16, n_s: int = 4, n_v: int | None = None, kernel: str = "uniform",
                 template=None, box_indices=(0, 1, 2, 3), adapt_rate: float = 0.0,
                 adapt_threshold: float = 0.8, name: str | None = None):
        super().__init__(variable, name=name)
        self.adapt_rate = float(check_finite_param(f"{self.name}.adapt_rate", adapt_rate,
                                                   nonneg=True))
        if self.adapt_rate > 1:
            raise ValueError(f"factor {self.name!r}: adapt_rate must be in [0, 1]")
        self.adapt_threshold = float(check_finite_param(f"{self.name}.adapt_threshold",
                                                        adapt_threshold))
        self.lam = float(check_finite_param(f"{self.name}.lam", lam, positive=True))
        self.layout, self.kernel = layout, kernel
        self.n_h, self.n_s = int(n_h), int(n_s)
        self.n_v = None if n_v is None else int(n_v)
        self.box_indices = tuple(int(i) for i in box_indices)
        if len(self.box_indices) != 4:
            raise ValueError(f"factor {self.name!r}: box_indices must have 4 entries")
        self.scorer = ColourHistogramScorer(layout=layout, n_h=self.n_h, n_s=self.n_s,
                                            n_v=self.n_v, kernel=kernel)
        self.template = None if template is None else np.asarray(template, dtype=float)
        if self.template is not None:
            check_finite_param(f"{self.name}.template", self.template, nonneg=True)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "layout": self.layout, "n_h": self.n_h,
                             "n_s": self.n_s, "kernel": self.kernel,
                             "box_indices": list(self.box_indices)}
        if self.n_v is not None:
            p["n_v"] = self.n_v
        if self.template is not None:
            p["template"] = self.template
        if self.adapt_rate > 0:
            p.update(adapt_rate=self.adapt_rate, adapt_threshold=self.adapt_threshold)
        return p

    @property
    def learns(self) -> bool:
        return self.adapt_rate > 0

    def update(self, estimates, scores, frame=None) -> None:
        """Blend the template towards the estimate's histogram when it matches well."""
        if self.adapt_rate <= 0 or frame is None or self.template is None:
            return
        x = np.asarray(estimates[self.variables[0]], dtype=float)[None]
        if self.rho(x, frame)[0] < self.adapt_threshold:
            return
        box = self.boxes(x)[0]
        current = np.asarray(self.scorer.template(frame, box), dtype=float)
        self.template = (1 - self.adapt_rate) * self.template + self.adapt_rate * current

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
        """Take the template from the first frame at the box ``value`` (if not given)."""
        if self.template is None:
            box = np.asarray(value, dtype=float)[list(self.box_indices)]
            self.template = np.asarray(self.scorer.template(ctx, box), dtype=float)

    def rho(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """Bhattacharyya coefficients ``(N,)`` (× in-image fraction of each box)."""
        if self.template is None:
            raise ValueError(f"factor {self.name!r} has no template: give one or run it from "
                             f"the first frame")
        return self.scorer.rho(ctx, self.boxes(x), self.template)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return -self.lam * (1.0 - self.rho(x, ctx))

    @property
    def batch_key(self):
        """Factors with equal bin layout and kernel share one scoring pass per frame."""
        return ("colour", self.layout, self.n_h, self.n_s, self.n_v, self.kernel)

    @classmethod
    def log_likelihood_batch(cls, factors, xs, ctx):
        """All the factors' boxes scored in one :meth:`ColourHistogramScorer.rho_many`."""
        if any(f.template is None for f in factors):
            raise ValueError("a colour factor has no template: run it from the first frame")
        boxes = np.concatenate([f.boxes(x) for f, x in zip(factors, xs, strict=True)])
        owner = np.repeat(np.arange(len(factors)), [len(x) for x in xs])
        rho = factors[0].scorer.rho_many(ctx, boxes, np.array([f.template for f in factors]),
                                         owner)
        lam = np.repeat([f.lam for f in factors], [len(x) for x in xs])
        out = -lam * (1.0 - rho)
        return np.split(out, np.cumsum([len(x) for x in xs])[:-1])


class FragmentsLikelihood(LikelihoodFactor):
    """Fragment-based colour likelihood (Adam, Rivlin & Shimshoni 2006, "FragTrack").

    The box is cut into a ``grid = (columns, rows)`` of sub-regions, each scored
    against its own template fragment (taken in the first frame) through the same
    integral histograms as :class:`ColourHistogramLikelihood` — all fragments of all
    particles in one pass (:meth:`ColourHistogramScorer.rho_many`) — and the fragment
    scores are combined robustly by their ``quantile``, so that a partly occluded object
    still scores on its visible part. The default is the median: with a third of the
    fragments hidden, any quantile below 1/3 lands on a hidden fragment (a test pins
    this); on FaceOcc1 a 3×3 grid scored AUC 0.850 with the median and 0.803 with the
    25 % quantile (3 seeds, 100 particles):

    .. math::
        \\log p(z \\mid X) = -\\lambda\\,(1 - Q_q\\{\\rho_f(X)\\}_f)
    """

    def __init__(self, variable: str, *, lam: float = 20.0, grid=(3, 3), quantile: float = 0.5,
                 layout: str = "perez", n_h: int = 16, n_s: int = 4, n_v: int | None = None,
                 templates=None, box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, name=name)
        self.lam = float(check_finite_param(f"{self.name}.lam", lam, positive=True))
        self.grid = (int(grid[0]), int(grid[1]))
        if min(self.grid) < 1:
            raise ValueError(f"factor {self.name!r}: grid must be positive, got {grid!r}")
        self.quantile = float(check_finite_param(f"{self.name}.quantile", quantile))
        if not 0.0 <= self.quantile <= 1.0:
            raise ValueError(f"factor {self.name!r}: quantile must be in [0, 1]")
        self.layout, self.n_h, self.n_s = layout, int(n_h), int(n_s)
        self.n_v = None if n_v is None else int(n_v)
        self.box_indices = tuple(int(i) for i in box_indices)
        self.scorer = ColourHistogramScorer(layout=layout, n_h=self.n_h, n_s=self.n_s,
                                            n_v=self.n_v)
        self.templates = None if templates is None else np.asarray(templates, dtype=float)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "grid": list(self.grid),
                             "quantile": self.quantile, "layout": self.layout, "n_h": self.n_h,
                             "n_s": self.n_s, "box_indices": list(self.box_indices)}
        if self.n_v is not None:
            p["n_v"] = self.n_v
        if self.templates is not None:
            p["templates"] = self.templates
        return p

    def fragments(self, boxes: np.ndarray) -> np.ndarray:
        """Sub-boxes ``(N * F, 4)`` of boxes ``(N, 4)``, fragment-major within each box."""
        gx, gy = self.grid
        b = np.asarray(boxes, dtype=float)
        fw, fh = b[:, 2] / gx, b[:, 3] / gy
        ix, iy = np.meshgrid(np.arange(gx), np.arange(gy))
        ox = (ix.ravel() + 0.5)[None, :] * fw[:, None] - b[:, 2:3] / 2
        oy = (iy.ravel() + 0.5)[None, :] * fh[:, None] - b[:, 3:4] / 2
        f = gx * gy
        return np.column_stack([(b[:, 0:1] + ox).ravel(), (b[:, 1:2] + oy).ravel(),
                                np.repeat(fw, f), np.repeat(fh, f)])

    def initialize(self, ctx: FrameContext, value: np.ndarray) -> None:
        if self.templates is None:
            box = np.asarray(value, dtype=float)[list(self.box_indices)][None]
            hist, in_frac = self.scorer.histograms(ctx, self.fragments(box))
            if np.any(in_frac <= 0):
                raise ValueError(f"factor {self.name!r}: a fragment of the initial box lies "
                                 f"outside the image")
            self.templates = hist / hist.sum(axis=1, keepdims=True)

    def fragment_rho(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N, F)`` Bhattacharyya coefficient of every fragment of every particle."""
        if self.templates is None:
            raise ValueError(f"factor {self.name!r} has no templates: run it from the first "
                             f"frame")
        boxes = x[:, list(self.box_indices)]
        f = self.grid[0] * self.grid[1]
        owner = np.tile(np.arange(f), len(boxes))
        rho = self.scorer.rho_many(ctx, self.fragments(boxes), self.templates, owner)
        return rho.reshape(len(boxes), f)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        rho = self.fragment_rho(x, ctx)
        return -self.lam * (1.0 - np.quantile(rho, self.quantile, axis=1))


class GradientLikelihood(LikelihoodFactor):
    """Oriented-gradient likelihood: the box's cell histograms of gradient orientation
    (integral images of gradient magnitude per orientation bin, computed once per frame
    and shared through the frame cache) against a template taken in the first frame.

    .. math::
        \\log p(z \\mid X) = -\\lambda\\,(1 - \\langle h(X), h_0 \\rangle)

    with ``h`` the L2-normalised concatenation of the ``cells`` orientation histograms.
    Unlike a whole-box colour histogram, the cell layout changes with the box size, so
    this cue can see scale; it multiplies with colour cues by declaring both.
    """

    def __init__(self, variable: str, *, lam: float = 20.0, n_orient: int = 9, cells=(3, 3),
                 template=None, box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, name=name)
        from .features import PatchFeatures

        self.lam = float(check_finite_param(f"{self.name}.lam", lam, positive=True))
        self.n_orient = int(n_orient)
        self.cells = (int(cells[0]), int(cells[1]))
        if self.n_orient < 2 or min(self.cells) < 1:
            raise ValueError(f"factor {self.name!r}: need n_orient >= 2 and positive cells")
        self.box_indices = tuple(int(i) for i in box_indices)
        self._features = PatchFeatures(n_orient=self.n_orient, cells=self.cells)
        self.template = None if template is None else np.asarray(template, dtype=float)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "n_orient": self.n_orient,
                             "cells": list(self.cells), "box_indices": list(self.box_indices)}
        if self.template is not None:
            p["template"] = self.template
        return p

    def descriptors(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N, n_orient · cells)`` L2-normalised gradient descriptors of particles ``x``."""
        return self._features.gradients(ctx, x[:, list(self.box_indices)])

    def initialize(self, ctx: FrameContext, value: np.ndarray) -> None:
        if self.template is None:
            self.template = self.descriptors(np.asarray(value, dtype=float)[None], ctx)[0]

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        if self.template is None:
            raise ValueError(f"factor {self.name!r} has no template: run it from the first "
                             f"frame")
        return -self.lam * (1.0 - self.descriptors(x, ctx) @ self.template)
