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

__all__ = ["ColourHistogramLikelihood"]


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
    """

    def __init__(self, variable: str, *, lam: float = 20.0, layout: str = "perez",
                 n_h: int = 16, n_s: int = 4, n_v: int | None = None, kernel: str = "uniform",
                 template=None, box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, name=name)
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
        return p

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
