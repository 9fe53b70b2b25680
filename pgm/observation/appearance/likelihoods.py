"""Appearance likelihood factors (image evidence for box-valued variables).

:class:`ColourHistogramLikelihood` — Pérez et al. [#perez2002]: the colour
histogram of the candidate box against a template histogram ``q``, through the
Bhattacharyya coefficient ``ρ``:

.. math::
    \\log p(z \\mid X) = -\\lambda\\,(1 - \\rho(X)) + \\mathrm{const}

All particles of a frame are scored in one vectorised pass
(:mod:`pgm.observation.appearance.colour`); the colour quantisation is cached on the frame and
shared with every other factor using the same bin layout.

Other factors here follow a paper too: :class:`FragmentsLikelihood` (Adam et al.
[#adam2006]), :class:`RotationInvariantLikelihood` and :class:`GMMKLLikelihood` (Wang et al.
[#wang2008]).

References
----------
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
.. [#nummiaro2003] K. Nummiaro, E. Koller-Meier and L. Van Gool, "An adaptive color-based
   particle filter", Image and Vision Computing 21(1), 99–110, 2003.
   doi:10.1016/S0262-8856(02)00129-4
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
.. [#adam2006] A. Adam, E. Rivlin and I. Shimshoni, "Robust fragments-based tracking using the
   integral histogram", Proc. CVPR 2006, vol. 1, 798–805. doi:10.1109/CVPR.2006.256
.. [#wang2008] J. Wang, Y. Yin and H. Man, "Multiple human tracking using particle filter with
   Gaussian process dynamical model", EURASIP J. Image and Video Processing 2008, Article
   ID 969456. doi:10.1155/2008/969456
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any, ClassVar

import cv2
import numpy as np

from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param
from pgm.core.variable import Variable
from pgm.factors import LikelihoodFactor
from pgm.observation.appearance.colour import ColourHistogramScorer, pixel_bounds
from pgm.observation.appearance.gmm import MixtureTemplate, SharedComponentKL, fit_template, literal_kl

__all__ = ["BoxAppearanceLikelihood", "ColourHistogramLikelihood", "FragmentsLikelihood",
           "GradientLikelihood", "RotationInvariantLikelihood", "GMMKLLikelihood",
           "ColourContrastLikelihood", "TemplateLikelihood"]



#: bounds of the sizes an appearance cue takes (bins, cells, rings, samples, ...): a
#: size is work and memory per particle and frame, so ``gradient(n_orient=1e6)`` is
#: refused when the factor is built, naming the option, not met as an out-of-memory
SIZE_BOUNDS = {"n_orient": (2, 36), "cells": (1, 16), "grid": (1, 64), "rings": (1, 64),
               "angles": (1, 360), "radial_samples": (1, 16), "n_components": (1, 64),
               "n_samples": (1, 65536), "n_h": (1, 180), "n_s": (1, 256), "n_v": (1, 256),
               "scales": (1, 15)}


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

    @abstractmethod
    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """Set the appearance model from frame ``ctx`` at the state ``value`` ``(d,)``."""

class ColourHistogramLikelihood(BoxAppearanceLikelihood):
    """Colour-histogram likelihood of a box variable ``(cx, cy, w, h, ...)``.

    Parameters
    ----------
    variable : str
        A variable whose components ``box_indices`` are ``(cx, cy, w, h)``.
    lam : float
        ``λ`` (default 20, as in [#perez2002]). The setting of [#zhang2015], garbled
        in the text ("2σ is Gaussian variance, the value is 0.2"), most plausibly means
        ``σ² = 0.2``, i.e. ``λ = 1/(2σ²) = 2.5``.
    layout : {"perez", "hsv", "rgb"}
        Bin layout: ``"perez"`` (the layout of [#perez2002]) keeps a value-only
        histogram for low-saturation pixels, so greyscale video works.
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
        Adaptive template (Nummiaro et al. [#nummiaro2003]), off at 0 (the default): after a frame
        whose score at the estimate has ``ρ ≥ adapt_threshold``, the template becomes
        ``(1 − adapt_rate) q + adapt_rate p(estimate)``.
    adapt_threshold : float
        ``π_T``: the Bhattacharyya coefficient required to adapt.
    """

    def __init__(self, variable: str, *, lam: float = 20.0, layout: str = "perez",
                 n_h: int = 16, n_s: int = 4, n_v: int | None = None, kernel: str = "uniform",
                 template=None, box_indices=(0, 1, 2, 3), adapt_rate: float = 0.0,
                 adapt_threshold: float = 0.8, name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, adapt_rate=adapt_rate,
                         name=name)
        self.adapt_threshold = float(check_finite_param(f"{self.name}.adapt_threshold",
                                                        adapt_threshold))
        self.layout, self.kernel = layout, kernel
        self.n_h, self.n_s, self.n_v = _bins(self.name, n_h, n_s, n_v)
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

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """The template: the colour histogram of the first frame's box."""
        box = value[list(self.box_indices)]
        self.template = np.asarray(self.scorer.template(ctx, box), dtype=float)

    def rho(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """Bhattacharyya coefficients ``(N,)`` (× in-image fraction of each box)."""
        self.require_model()
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


class FragmentsLikelihood(BoxAppearanceLikelihood):
    """Fragment-based colour likelihood ("FragTrack" of Adam, Rivlin & Shimshoni [#adam2006]).

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

    model_attr = "templates"

    def __init__(self, variable: str, *, lam: float = 20.0, grid=(3, 3), quantile: float = 0.5,
                 layout: str = "perez", n_h: int = 16, n_s: int = 4, n_v: int | None = None,
                 templates=None, box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, name=name)
        self.grid = _bounded_pair(self.name, "grid", grid)
        self.quantile = float(check_finite_param(f"{self.name}.quantile", quantile))
        if not 0.0 <= self.quantile <= 1.0:
            raise ValueError(f"factor {self.name!r}: quantile must be in [0, 1]")
        self.layout = layout
        self.n_h, self.n_s, self.n_v = _bins(self.name, n_h, n_s, n_v)
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

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """One template histogram per fragment of the first frame's box."""
        box = value[list(self.box_indices)][None]
        hist, in_frac = self.scorer.histograms(ctx, self.fragments(box))
        if np.any(in_frac <= 0):
            raise ValueError(f"factor {self.name!r}: a fragment of the initial box lies "
                             f"outside the image")
        self.templates = hist / hist.sum(axis=1, keepdims=True)

    def fragment_rho(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N, F)`` Bhattacharyya coefficient of every fragment of every particle."""
        self.require_model()
        boxes = self.boxes(x)
        f = self.grid[0] * self.grid[1]
        owner = np.tile(np.arange(f), len(boxes))
        rho = self.scorer.rho_many(ctx, self.fragments(boxes), self.templates, owner)
        return rho.reshape(len(boxes), f)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        rho = self.fragment_rho(x, ctx)
        return -self.lam * (1.0 - np.quantile(rho, self.quantile, axis=1))


class GradientLikelihood(BoxAppearanceLikelihood):
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
        super().__init__(variable, lam=lam, box_indices=box_indices, name=name)
        from pgm.observation.appearance.features import PatchFeatures

        self.n_orient = bounded_int(self.name, "n_orient", n_orient)
        self.cells = _bounded_pair(self.name, "cells", cells)
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
        return self._features.gradients(ctx, self.boxes(x))

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """The template: the first frame's descriptor at ``value``."""
        self.template = self.descriptors(value[None], ctx)[0]

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        self.require_model()
        return -self.lam * (1.0 - self.descriptors(x, ctx) @ self.template)


class RotationInvariantLikelihood(BoxAppearanceLikelihood):
    r"""The rotation-invariant ring model of Wang et al. [#wang2008], §3.2.7 (eq. (7)).

    Pixels in a reference circle around the box centre are grouped into ``rings``
    concentric rings; each ring's colour is summarised per channel by a Gaussian
    ``(μ, σ²)``, so rotating the patch about its centre leaves the model unchanged.
    The dissimilarity to the template (eq. 7, averaged over rings and channels) is

    .. math::
        \Gamma = \frac{1}{2N}\sum_{n=1}^{N}\Big[(\mu_B - \mu_A)^2
        \Big(\frac{1}{\sigma_A^2} + \frac{1}{\sigma_B^2}\Big)
        + \frac{\sigma_B^2}{\sigma_A^2} + \frac{\sigma_A^2}{\sigma_B^2}\Big] \ge 1,

    and the likelihood is ``exp(−λ (Γ − 1))`` (``Γ − 1``: eq. 7's minimum is 1). All
    particles are scored at once from a fixed polar grid of sample points
    (``rings × radial_samples × angles`` per particle, one gather), so this is a grid
    approximation of the ring integrals; with ``angles`` divisible by 4 it is exactly
    invariant to quarter turns. The circle's radius is ``radius_scale · sqrt(w h) / 2``.
    """

    def __init__(self, variable: str, *, lam: float = 2.0, rings: int = 4, angles: int = 24,
                 radial_samples: int = 2, radius_scale: float = 1.0, template=None,
                 min_var: float = 4.0, box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, name=name)
        self.rings = bounded_int(self.name, "rings", rings)
        self.angles = bounded_int(self.name, "angles", angles)
        self.radial_samples = bounded_int(self.name, "radial_samples", radial_samples)
        self.radius_scale = float(check_finite_param(f"{self.name}.radius_scale",
                                                     radius_scale, positive=True))
        self.min_var = float(check_finite_param(f"{self.name}.min_var", min_var,
                                                positive=True))
        self.template = None if template is None else np.asarray(template, dtype=float)
        k = np.arange(self.rings * self.radial_samples)
        self._radii = (k + 0.5) / (self.rings * self.radial_samples)  # in units of R
        theta = 2 * np.pi * np.arange(self.angles) / self.angles
        self._cos, self._sin = np.cos(theta), np.sin(theta)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "rings": self.rings, "angles": self.angles,
                             "radial_samples": self.radial_samples,
                             "radius_scale": self.radius_scale, "min_var": self.min_var,
                             "box_indices": list(self.box_indices)}
        if self.template is not None:
            p["template"] = self.template
        return p

    def ring_stats(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N, rings, channels, 2)``: per-ring mean and variance of each channel."""
        img = ctx.image
        H, W = img.shape[:2]
        b = self.boxes(x)
        R = 0.5 * self.radius_scale * np.sqrt(np.maximum(b[:, 2] * b[:, 3], 1e-9))
        r = R[:, None, None] * self._radii[None, :, None]  # (N, K·S, 1)
        px = b[:, 0, None, None] + r * self._cos[None, None, :]
        py = b[:, 1, None, None] + r * self._sin[None, None, :]
        xi = np.clip(np.floor(px), 0, W - 1).astype(np.intp)
        yi = np.clip(np.floor(py), 0, H - 1).astype(np.intp)
        c = 1 if img.ndim == 2 else img.shape[2]
        flat = np.ascontiguousarray(img).reshape(-1)
        idx = ((yi * W + xi) * c).reshape(len(b), self.rings, -1)  # (N, rings, samples)
        m = idx.shape[2]
        out = np.empty((len(b), self.rings, c, 2))
        for ch in range(c):  # one gather per colour channel, all particles at once
            v = flat[idx + ch].astype(np.float32)
            mean = v.sum(axis=2, dtype=np.float64) / m
            sq = np.einsum("nks,nks->nk", v, v, dtype=np.float64) / m
            out[:, :, ch, 0] = mean
            out[:, :, ch, 1] = np.maximum(sq - mean * mean, self.min_var)
        return out

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """The template: the first frame's ring statistics at ``value``."""
        self.template = self.ring_stats(value[None], ctx)[0]

    def gamma(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``Γ`` of eq. 7 for every particle, ``(N,)`` (1 = identical)."""
        self.require_model()
        s = self.ring_stats(x, ctx)
        mu_b, var_b = s[..., 0], s[..., 1]
        mu_a, var_a = self.template[..., 0], self.template[..., 1]
        terms = ((mu_b - mu_a) ** 2 * (1 / var_a + 1 / var_b) + var_b / var_a + var_a / var_b)
        return terms.reshape(len(x), -1).mean(axis=1) / 2.0

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return -self.lam * (self.gamma(x, ctx) - 1.0)


class GMMKLLikelihood(BoxAppearanceLikelihood):
    r"""GMM-KL appearance (Wang et al. [#wang2008], §3.2.6, eq. (6)): a Gaussian mixture over
    RGB fitted to the template's pixels in the first frame (scikit-learn), the
    Monte-Carlo KL divergence ``D`` of eq. 6 between it and the candidate's mixture, and

    .. math::
        \log p(z \mid X) = -\lambda\, D(X)

    (the paper's likelihood "proportional to the KL distance" inverted: a larger
    divergence must score lower).

    ``method="shared"`` (default) scores every particle without fitting a mixture per
    particle: the candidate's mixture keeps the template's components plus a uniform
    outlier component and re-estimates only the weights, by one EM step whose per-pixel
    responsibilities are computed once per frame and summed per box through integral
    images (:class:`pgm.observation.appearance.gmm.SharedComponentKL`). ``method="literal"`` fits
    a mixture to every box (:func:`pgm.observation.appearance.gmm.literal_kl`): the slow reference,
    for small cases. On a synthetic scan across an object the two rank candidates with
    Spearman correlation ≥ 0.9 and share the minimum (a test checks this).

    Parameters
    ----------
    lam : float
        ``λ`` (default 20: on FaceOcc1 and Crossing, one node with 100 particles and 3
        seeds, λ = 20 tracked better than 0.5 or 5 on both).
    n_components : int
        Template mixture components (default 4).
    symmetric : bool
        Both terms of eq. 6 (default) or the one-sided version.
    outlier_weight : float
        The template's weight on the outlier component (shared method).
    n_samples : int
        Template pixels kept for the Monte-Carlo template term.
    weights, means, covariances, samples : array_like, optional
        A fitted template (saved with the model); learned in the first frame if omitted.
    """

    def __init__(self, variable: str, *, lam: float = 20.0, n_components: int = 4,
                 symmetric: bool = True, method: str = "shared", outlier_weight: float = 0.01,
                 n_samples: int = 256, seed: int = 0, weights=None, means=None,
                 covariances=None, samples=None, box_indices=(0, 1, 2, 3),
                 name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, name=name)
        self.n_components = bounded_int(self.name, "n_components", n_components)
        self.n_samples = bounded_int(self.name, "n_samples", n_samples)
        if method not in ("shared", "literal"):
            raise ValueError(f"factor {self.name!r}: method must be 'shared' or 'literal', "
                             f"got {method!r}")
        self.method, self.symmetric, self.seed = method, bool(symmetric), int(seed)
        self.outlier_weight = float(check_finite_param(f"{self.name}.outlier_weight",
                                                       outlier_weight, positive=True))
        if self.outlier_weight >= 1:
            raise ValueError(f"factor {self.name!r}: outlier_weight must be below 1")
        self.template = None
        self._kl = None
        given = [a is not None for a in (weights, means, covariances, samples)]
        if any(given):
            if not all(given):
                raise ValueError(f"factor {self.name!r}: give all of weights, means, "
                                 f"covariances and samples, or none")
            try:
                self._set_template(MixtureTemplate(weights, means, covariances, samples))
            except ValueError as exc:
                raise ValueError(f"factor {self.name!r}: {exc}") from None

    def _set_template(self, template) -> None:
        self.template = template
        self._kl = SharedComponentKL(template, self.outlier_weight, self.symmetric)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "n_components": self.n_components,
                             "symmetric": self.symmetric, "method": self.method,
                             "outlier_weight": self.outlier_weight,
                             "n_samples": self.n_samples, "seed": self.seed,
                             "box_indices": list(self.box_indices)}
        if self.template is not None:
            t = self.template
            p.update(weights=t.weights, means=t.means, covariances=t.covariances,
                     samples=t.samples)
        return p

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """The template mixture, fitted to the first frame's box pixels."""
        box = value[list(self.box_indices)]
        self._set_template(fit_template(ctx.image, box, n_components=self.n_components,
                                        n_samples=self.n_samples, seed=self.seed))

    def divergence(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``D`` of eq. 6 for every particle, ``(N,)``."""
        self.require_model()
        boxes = self.boxes(x)
        if self.method == "literal":
            return literal_kl(ctx.image, boxes, self.template, symmetric=self.symmetric,
                              seed=self.seed)
        return self._kl.divergence(ctx, boxes)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return -self.lam * self.divergence(x, ctx)


class ColourContrastLikelihood(BoxAppearanceLikelihood):
    r"""Foreground/background colour log-odds summed over the box: a colour cue that
    sees scale.

    In the first frame, the colour histogram of the box (object, ``h_o``) and of a
    surrounding ring (the box grown by ``context`` of its size on every side, minus the
    box: background, ``h_b``) give each colour bin the log-odds
    ``l_b = log((h_o(b) + δ) / (h_b(b) + δ))``, clipped to ``±clip``. A candidate box
    scores the sum of its pixels' log-odds over the first box's area ``A_0``:

    .. math::
        \log p(z \mid X) = \lambda\, \frac{1}{A_0} \sum_{x \in X} l_{b(x)}

    Unlike a normalised histogram, this sum is largest for the box that holds the
    object's pixels and no background: a smaller box loses object pixels, a larger one
    adds background pixels with negative log-odds, so the cue sees scale (a test pins
    this). It reuses the frame's cached colour quantisation and one integral image of
    the log-odds over the particles' union region. With ``adapt_rate > 0`` the two
    histograms are re-estimated around the estimate each frame (blended at that rate),
    so the background model follows a moving camera.
    """

    model_attr = "object_hist"

    def __init__(self, variable: str, *, lam: float = 10.0, context: float = 0.5,
                 clip: float = 3.0, delta: float = 1e-3, adapt_rate: float = 0.0,
                 layout: str = "perez", n_h: int = 16, n_s: int = 4, n_v: int | None = None,
                 object_hist=None, background_hist=None, ref_area: float | None = None,
                 box_indices=(0, 1, 2, 3), name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, adapt_rate=adapt_rate,
                         name=name)
        self.context = float(check_finite_param(f"{self.name}.context", context,
                                                positive=True))
        self.clip = float(check_finite_param(f"{self.name}.clip", clip, positive=True))
        self.delta = float(check_finite_param(f"{self.name}.delta", delta, positive=True))
        self.layout = layout
        self.n_h, self.n_s, self.n_v = _bins(self.name, n_h, n_s, n_v)
        self.scorer = ColourHistogramScorer(layout=layout, n_h=self.n_h, n_s=self.n_s,
                                            n_v=self.n_v)
        given = [a is not None for a in (object_hist, background_hist, ref_area)]
        if any(given) and not all(given):
            raise ValueError(f"factor {self.name!r}: give object_hist, background_hist and "
                             f"ref_area together, or none")
        self.object_hist = self.background_hist = self.ref_area = None
        if all(given):
            self._set(np.asarray(object_hist, float), np.asarray(background_hist, float),
                      float(check_finite_param(f"{self.name}.ref_area", ref_area,
                                               positive=True)))

    def _set(self, obj: np.ndarray, bg: np.ndarray, ref_area: float) -> None:
        for what, h in (("object_hist", obj), ("background_hist", bg)):
            if h.shape != (self.scorer.n_bins,):
                raise ValueError(f"factor {self.name!r}: {what} must have "
                                 f"{self.scorer.n_bins} bins, got shape {h.shape}")
            check_finite_param(f"{self.name}.{what}", h, nonneg=True)
        self.object_hist = obj / max(obj.sum(), 1e-12)
        self.background_hist = bg / max(bg.sum(), 1e-12)
        self.ref_area = ref_area
        self.log_odds = np.clip(np.log((self.object_hist + self.delta)
                                       / (self.background_hist + self.delta)),
                                -self.clip, self.clip)
        self._key = hash(self.log_odds.tobytes())

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "context": self.context, "clip": self.clip,
                             "delta": self.delta, "adapt_rate": self.adapt_rate,
                             "layout": self.layout, "n_h": self.n_h, "n_s": self.n_s,
                             "box_indices": list(self.box_indices)}
        if self.n_v is not None:
            p["n_v"] = self.n_v
        if self.object_hist is not None:
            p.update(object_hist=self.object_hist, background_hist=self.background_hist,
                     ref_area=self.ref_area)
        return p

    def _histograms(self, ctx: FrameContext, box: np.ndarray):
        """Object and surrounding-ring histograms (counts) of one box."""
        grown = box.copy()
        grown[2:] *= 1.0 + 2.0 * self.context
        hist, frac = self.scorer.histograms(ctx, np.array([box, grown]))
        x0, x1, y0, y1 = pixel_bounds(np.array([box, grown]), *ctx.shape)
        counts = hist * ((x1 - x0) * (y1 - y0))[:, None]  # normalised: back to counts
        return counts[0], np.maximum(counts[1] - counts[0], 0.0), frac

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """Object and background histograms of the first frame's box and its ring."""
        box = value[list(self.box_indices)]
        obj, bg, frac = self._histograms(ctx, box)
        if frac[0] <= 0 or obj.sum() <= 0:
            raise ValueError(f"factor {self.name!r}: the initial box lies outside the "
                             f"image")
        self._set(obj, bg, float(box[2] * box[3]))

    def update(self, estimates, scores, frame=None) -> None:
        """Blend both histograms towards those around the estimate."""
        if self.adapt_rate <= 0 or frame is None or self.object_hist is None:
            return
        box = np.asarray(estimates[self.variables[0]], dtype=float)[list(self.box_indices)]
        obj, bg, frac = self._histograms(frame, box)
        if frac[0] <= 0 or obj.sum() <= 0 or bg.sum() <= 0:
            return
        r = self.adapt_rate
        self._set((1 - r) * self.object_hist + r * obj / obj.sum(),
                  (1 - r) * self.background_hist + r * bg / bg.sum(), self.ref_area)

    def box_sums(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N,)`` sum of the log-odds over each particle's box (in-image pixels)."""
        self.require_model()
        b = self.boxes(x)
        x0, x1, y0, y1 = pixel_bounds(b, *ctx.shape)
        region = (int(x0.min()), int(x1.max()), int(y0.min()), int(y1.max()))
        if region[0] >= region[1] or region[2] >= region[3]:
            return np.zeros(len(b))

        def integral():
            bins = self.scorer._frame(ctx).ensure(*region)[region[2]:region[3],
                                                           region[0]:region[1]]
            return cv2.integral(self.log_odds[bins], sdepth=cv2.CV_64F)

        ii = ctx.cached(("contrast", self._key) + region, integral)
        x0, x1, y0, y1 = x0 - region[0], x1 - region[0], y0 - region[2], y1 - region[2]
        return ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        return self.lam * self.box_sums(x, ctx) / self.ref_area


def grey_frame(ctx: FrameContext) -> np.ndarray:
    """The frame as ``float32`` grey levels, computed once per frame (cached)."""
    def make():
        img = ctx.image
        if img is None:
            raise ValueError(f"frame {ctx.index} has no image")
        grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        return np.ascontiguousarray(grey, dtype=np.float32)

    return ctx.cached(("grey-f32",), make)


class TemplateLikelihood(BoxAppearanceLikelihood):
    r"""Grey-level template matching by zero-mean normalised cross-correlation (NCC).

    Every box is read on a fixed ``grid = (columns, rows)`` of sample points placed
    relative to the box (nearest pixel; one gather for all particles), and the samples'
    zero-mean, unit-norm vector is correlated with the template's, taken in the first
    frame:

    .. math::
        \log p(z \mid X) = -\lambda\, (1 - \mathrm{NCC}(X))

    Because the grid scales with the box, a box of the wrong size reads the object's
    structure at the wrong places: this cue sees scale. NCC ignores brightness and
    contrast changes. With ``adapt_rate > 0`` the template is blended towards the
    estimate's samples after each frame.
    """

    def __init__(self, variable: str, *, lam: float = 20.0, grid=(12, 24),
                 adapt_rate: float = 0.0, template=None, box_indices=(0, 1, 2, 3),
                 name: str | None = None):
        super().__init__(variable, lam=lam, box_indices=box_indices, adapt_rate=adapt_rate,
                         name=name)
        self.grid = _bounded_pair(self.name, "grid", grid)
        if self.grid[0] * self.grid[1] < 2:
            raise ValueError(f"factor {self.name!r}: grid must be positive with at least 2 "
                             f"points, got {grid!r}")
        self.template = None
        if template is not None:
            t = np.asarray(template, dtype=float).reshape(-1)
            if t.shape != (self.grid[0] * self.grid[1],):
                raise ValueError(f"factor {self.name!r}: template must have "
                                 f"{self.grid[0] * self.grid[1]} samples, got {t.shape}")
            self.template = self._normalise(check_finite_param(f"{self.name}.template", t))
        gx, gy = self.grid
        self._u = (np.arange(gx) + 0.5) / gx - 0.5
        self._v = (np.arange(gy) + 0.5) / gy - 0.5

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"lam": self.lam, "grid": list(self.grid),
                             "box_indices": list(self.box_indices)}
        if self.adapt_rate > 0:
            p["adapt_rate"] = self.adapt_rate
        if self.template is not None:
            p["template"] = self.template
        return p

    @staticmethod
    def _normalise(v: np.ndarray) -> np.ndarray:
        v = v - v.mean(axis=-1, keepdims=True)
        return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-6)

    def samples(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """``(N, columns · rows)`` zero-mean unit-norm grey samples of each particle's box."""
        img = grey_frame(ctx)
        H, W = img.shape
        b = self.boxes(x)
        px = b[:, 0, None] + b[:, 2, None] * self._u[None, :]  # (N, gx)
        py = b[:, 1, None] + b[:, 3, None] * self._v[None, :]  # (N, gy)
        xi = np.clip(np.floor(px), 0, W - 1).astype(np.intp)
        yi = np.clip(np.floor(py), 0, H - 1).astype(np.intp)
        flat = (yi[:, :, None] * W + xi[:, None, :]).reshape(len(b), -1)  # row-major grid
        return self._normalise(img.reshape(-1)[flat].astype(np.float64))

    def learn(self, ctx: FrameContext, value: np.ndarray) -> None:
        """The template: the first frame's grey samples at ``value``."""
        self.template = self.samples(value[None], ctx)[0]

    def update(self, estimates, scores, frame=None) -> None:
        """Blend the template towards the estimate's samples."""
        if self.adapt_rate <= 0 or frame is None or self.template is None:
            return
        s = self.samples(np.asarray(estimates[self.variables[0]], dtype=float)[None], frame)[0]
        self.template = self._normalise((1 - self.adapt_rate) * self.template
                                        + self.adapt_rate * s)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        self.require_model()
        return -self.lam * (1.0 - self.samples(x, ctx) @ self.template)
