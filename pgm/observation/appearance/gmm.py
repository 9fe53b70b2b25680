"""Gaussian-mixture colour models and the Kullback–Leibler score of [#wang2008], §3.2.6.

Wang et al. fit a Gaussian mixture ``p1`` to the template's RGB pixels and one, ``p2``, to
each candidate region, and scores the candidate by the Monte-Carlo estimate of the
symmetric KL divergence (eq. 6)::

    D(p1, p2) = 1/n1 Σ_{x ∈ template} log p1(x)/p2(x) + 1/n2 Σ_{x ∈ candidate} log p2(x)/p1(x)

Fitting a mixture per particle per frame (:func:`literal_kl`, kept as the reference)
costs an EM run per particle. :class:`SharedComponentKL` avoids it: both mixtures
live on one dictionary of components — the template's ``K`` Gaussians plus one
uniform *outlier* component over the colour cube, which absorbs colours the template
does not have — and differ only in their weights. The candidate's weights are one EM
step from the template's, ``π2_k = mean_{x ∈ box} r_k(x)`` with ``r_k(x) ∝ π1_k φ_k(x)``
the per-pixel responsibilities, which are computed once per frame over the region the
particles cover and summed per box through ``K + 1`` integral images (responsibilities
are read from a lookup table over the colour cube at 64 levels per channel, built once
from the template, so a frame costs one gather per pixel). With these
responsibilities the EM lower bound of the candidate term is exactly ``KL(π2 ‖ π1)``
between the weight vectors (the per-pixel densities cancel), and the template term is
evaluated exactly on a fixed sample of template pixels, ``S`` per particle. No mixture
is fitted after the first frame.

>>> import numpy as np
>>> from pgm.observation.appearance.gmm import fit_template, SharedComponentKL
>>> rng = np.random.default_rng(0)
>>> img = rng.integers(0, 40, (60, 80, 3)).astype(np.uint8)
>>> img[20:40, 30:50] = (200, 30, 30)
>>> model = fit_template(img, np.array([40.0, 30.0, 20.0, 20.0]), n_components=2)
>>> d = SharedComponentKL(model).divergence(img, np.array([[40.0, 30, 20, 20], [15, 30, 20, 20]]))
>>> bool(d[0] < d[1])
True

References
----------
.. [#wang2008] J. Wang, Y. Yin and H. Man, "Multiple human tracking using particle filter with
   Gaussian process dynamical model", EURASIP J. Image and Video Processing 2008, Article
   ID 969456. doi:10.1155/2008/969456
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import logsumexp

from pgm.observation.appearance.colour import pixel_bounds

__all__ = ["MixtureTemplate", "fit_template", "component_logpdf", "box_pixels",
           "SharedComponentKL", "literal_kl"]

_LOG2PI = np.log(2 * np.pi)


def _features(image: np.ndarray) -> np.ndarray:
    """``(H, W, C)`` float pixels in [0, 1]: RGB for a BGR colour image, grey otherwise."""
    img = np.asarray(image)
    if img.ndim == 2:
        return img[..., None].astype(np.float64) / 255.0
    return img[..., ::-1].astype(np.float64) / 255.0


def box_pixels(image: np.ndarray, box) -> np.ndarray:
    """``(n, C)`` feature pixels (RGB in [0, 1]) inside one box ``(cx, cy, w, h)``."""
    img = np.asarray(image)
    x0, x1, y0, y1 = (int(v[0]) for v in pixel_bounds(np.asarray(box, float), *img.shape[:2]))
    return _features(img[y0:y1, x0:x1]).reshape(-1, 1 if img.ndim == 2 else 3)


@dataclass(frozen=True)
class MixtureTemplate:
    """A Gaussian mixture ``(weights (K,), means (K, C), covariances (K, C, C))`` over
    pixel colours in [0, 1], with ``samples (S, C)`` — template pixels for the Monte-Carlo
    term of eq. 6."""

    weights: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    samples: np.ndarray

    def __post_init__(self):
        w, m, c, s = (np.asarray(a, dtype=float) for a in
                      (self.weights, self.means, self.covariances, self.samples))
        k = len(w)
        if w.ndim != 1 or k < 1 or m.shape[0] != k or m.ndim != 2:
            raise ValueError(f"mixture template: weights {w.shape} and means {m.shape} disagree")
        dim = m.shape[1]
        if c.shape != (k, dim, dim) or s.ndim != 2 or s.shape[1] != dim or len(s) == 0:
            raise ValueError(f"mixture template: covariances {c.shape} / samples {s.shape} do "
                             f"not fit {k} components of dimension {dim}")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(m)) and np.all(np.isfinite(c))
                and np.all(np.isfinite(s))) or np.any(w < 0) or w.sum() <= 0:
            raise ValueError("mixture template: weights must be non-negative and all "
                             "parameters finite")
        try:
            chol = np.linalg.cholesky(c)
        except np.linalg.LinAlgError:
            raise ValueError("mixture template: a covariance is not positive definite") from None
        # normalise only weights that are not already (to rounding): renormalising a
        # normalised vector can move it by an ulp, and a saved model must reload exactly
        if abs(w.sum() - 1.0) > 1e-9:
            w = w / w.sum()
        for name, a in (("weights", w), ("means", m), ("covariances", c),
                        ("samples", s), ("_chol", chol)):
            object.__setattr__(self, name, a)

    @property
    def n_components(self) -> int:
        return len(self.weights)

    @property
    def dim(self) -> int:
        return self.means.shape[1]

    def component_logpdf(self, x: np.ndarray) -> np.ndarray:
        """``(n, K)`` log-density of every component at points ``x`` ``(n, C)``."""
        return component_logpdf(x, self.means, self._chol)

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        """``(n,)`` log-density of the mixture."""
        return logsumexp(self.component_logpdf(x) + np.log(self.weights), axis=1)


def component_logpdf(x: np.ndarray, means: np.ndarray, chol: np.ndarray) -> np.ndarray:
    """``(n, K)`` Gaussian log-densities at ``x`` ``(n, C)``; ``chol`` the covariances'
    lower Cholesky factors ``(K, C, C)``."""
    x = np.asarray(x, dtype=float)
    n, dim = x.shape
    out = np.empty((n, len(means)))
    for k in range(len(means)):  # a loop over mixture components, not pixels or boxes
        d = (x - means[k]).T
        z = np.linalg.solve(chol[k], d) if dim > 1 else d / chol[k][0, 0]
        out[:, k] = (-0.5 * np.einsum("ij,ij->j", z, z) - np.log(np.diag(chol[k])).sum()
                     - 0.5 * dim * _LOG2PI)
    return out


def _fit(pixels: np.ndarray, n_components: int, seed: int, reg_covar: float):
    from sklearn.mixture import GaussianMixture

    k = max(1, min(int(n_components), len(pixels)))
    gm = GaussianMixture(k, covariance_type="full", reg_covar=reg_covar, random_state=seed,
                         max_iter=200, n_init=1)
    gm.fit(pixels)
    return gm.weights_, gm.means_, gm.covariances_


def fit_template(image: np.ndarray, box, *, n_components: int = 4, n_samples: int = 256,
                 max_fit_pixels: int = 4000, reg_covar: float = 1e-3,
                 seed: int = 0) -> MixtureTemplate:
    """Fit the template mixture (scikit-learn, full covariances) to the pixels of ``box``.

    At most ``max_fit_pixels`` pixels (an even stride) are used for the fit and
    ``n_samples`` are kept for the Monte-Carlo template term; both subsets are
    deterministic, and the fit is seeded with ``seed``.
    """
    pix = box_pixels(image, box)
    if len(pix) < 2:
        raise ValueError(f"GMM-KL template box {np.asarray(box).tolist()} covers fewer than 2 "
                         f"pixels of the image")
    fit_pix = pix[np.linspace(0, len(pix) - 1, min(len(pix), max_fit_pixels)).astype(int)]
    w, m, c = _fit(fit_pix, n_components, seed, reg_covar)
    samples = pix[np.linspace(0, len(pix) - 1, min(len(pix), n_samples)).astype(int)]
    return MixtureTemplate(w, m, c, samples)


class SharedComponentKL:
    """Eq. 6 for many boxes at once, on the template's components plus an outlier.

    Parameters
    ----------
    template : MixtureTemplate
    outlier_weight : float
        ``ε``: the template's weight on the uniform outlier component (its own
        components share ``1 − ε``).
    symmetric : bool
        Eq. 6 (both terms, default) or its one-sided version (the template term).
    """

    def __init__(self, template: MixtureTemplate, outlier_weight: float = 0.01,
                 symmetric: bool = True):
        if not 0.0 < outlier_weight < 1.0:
            raise ValueError(f"outlier_weight must be in (0, 1), got {outlier_weight!r}")
        self.template = template
        self.symmetric = bool(symmetric)
        self.log_pi1 = np.log(np.append((1 - outlier_weight) * template.weights,
                                        outlier_weight))
        # template samples: component densities, shifted per sample for stability
        lp = np.column_stack([template.component_logpdf(template.samples),
                              np.zeros(len(template.samples))])  # uniform on [0,1]^C: log 1
        self._shift = lp.max(axis=1)
        self._phi_samples = np.exp(lp - self._shift[:, None]).T  # (K+1, S)
        self._logp1_samples = logsumexp(lp + self.log_pi1, axis=1)
        self.fingerprint = hash((self.log_pi1.tobytes(), template.means.tobytes(),
                                 template.covariances.tobytes(), self.symmetric))
        # responsibilities of every colour cell: 64 levels per channel (256 for grey)
        dim = template.dim
        if dim not in (1, 3):
            raise ValueError(f"GMM-KL needs 1 (grey) or 3 (RGB) channels, got {dim}")
        self._shift_bits = 0 if dim == 1 else 2
        levels = 256 >> self._shift_bits
        centres = (np.arange(levels) * (1 << self._shift_bits)
                   + ((1 << self._shift_bits) - 1) / 2) / 255.0
        grid = (centres[:, None] if dim == 1 else
                np.stack(np.meshgrid(centres, centres, centres, indexing="ij"), -1).reshape(-1, 3))
        self._lut = self.exact_responsibilities(grid).astype(np.float32)

    def exact_responsibilities(self, pixels: np.ndarray) -> np.ndarray:
        """``(n, K+1)`` responsibilities ``r_k(x) ∝ π1_k φ_k(x)`` of pixels ``(n, C)``."""
        lp = np.column_stack([self.template.component_logpdf(pixels), np.zeros(len(pixels))])
        lp += self.log_pi1
        lp -= logsumexp(lp, axis=1, keepdims=True)
        return np.exp(lp)

    def cell_index(self, image: np.ndarray) -> np.ndarray:
        """The lookup-table cell of every pixel of a BGR (or grey) ``uint8`` image."""
        img = np.asarray(image)
        if img.ndim == 2:
            return img.astype(np.intp)
        if img.dtype != np.uint8:
            img = np.clip(np.round(img), 0, 255).astype(np.uint8)
        q = (img >> 2).astype(np.intp)
        return (q[..., 2] << 12) | (q[..., 1] << 6) | q[..., 0]  # RGB order

    def responsibilities(self, image: np.ndarray) -> np.ndarray:
        """``(H, W, K+1)`` responsibilities of an image's pixels (lookup table)."""
        return self._lut[self.cell_index(image)]

    def integrals(self, image: np.ndarray, region) -> np.ndarray:
        """``(h+1, w+1, K+1)`` integral images of the responsibilities over ``region``
        ``(x0, x1, y0, y1)`` of the image."""
        x0, x1, y0, y1 = region
        r = self.responsibilities(np.asarray(image)[y0:y1, x0:x1])
        if r.shape[0] == 0 or r.shape[1] == 0:
            return np.zeros((r.shape[0] + 1, r.shape[1] + 1, r.shape[2]))
        ii = cv2.integral(np.ascontiguousarray(r), sdepth=cv2.CV_64F)
        return ii.reshape(r.shape[0] + 1, r.shape[1] + 1, r.shape[2])

    def weights_of(self, counts: np.ndarray) -> np.ndarray:
        """Candidate weights ``π2`` ``(N, K+1)`` from responsibility sums ``(N, K+1)``;
        an empty box gets all its weight on the outlier."""
        n2 = counts.sum(axis=1, keepdims=True)
        empty = n2[:, 0] <= 0
        pi2 = counts / np.where(n2 > 0, n2, 1.0)
        pi2[empty] = 0.0
        pi2[empty, -1] = 1.0
        return pi2

    def divergence_from_weights(self, pi2: np.ndarray) -> np.ndarray:
        """``D`` ``(N,)`` of candidates with weights ``pi2`` ``(N, K+1)``."""
        p2 = pi2 @ self._phi_samples  # (N, S)
        logp2 = np.log(np.maximum(p2, 1e-300)) + self._shift
        d = (self._logp1_samples - logp2).mean(axis=1)
        if self.symmetric:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(pi2 > 0, pi2 * (np.log(np.where(pi2 > 0, pi2, 1.0)) - self.log_pi1),
                             0.0)
            d = d + t.sum(axis=1)
        return d

    def divergence(self, image_or_ctx, boxes: np.ndarray) -> np.ndarray:
        """``D`` ``(N,)`` of boxes ``(N, 4)`` ``(cx, cy, w, h)``; the per-pixel work is
        done once over the boxes' union (cached on a :class:`~pgm.core.frame.FrameContext`)."""
        from pgm.core.frame import FrameContext

        ctx = image_or_ctx if isinstance(image_or_ctx, FrameContext) else FrameContext(
            0, image_or_ctx)
        b = np.asarray(boxes, dtype=float).reshape(-1, 4)
        if len(b) == 0:
            return np.zeros(0)
        H, W = ctx.shape
        x0, x1, y0, y1 = pixel_bounds(b, H, W)
        region = (int(x0.min()), int(x1.max()), int(y0.min()), int(y1.max()))
        ii = ctx.cached(("gmm-kl", self.fingerprint) + region,
                        lambda: self.integrals(ctx.image, region))
        x0, x1, y0, y1 = x0 - region[0], x1 - region[0], y0 - region[2], y1 - region[2]
        counts = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
        return self.divergence_from_weights(self.weights_of(np.maximum(counts, 0.0)))


def literal_kl(image: np.ndarray, boxes: np.ndarray, template: MixtureTemplate, *,
               symmetric: bool = True, reg_covar: float = 1e-3, seed: int = 0) -> np.ndarray:
    """Eq. (6) of [#wang2008] as written: a mixture fitted to every candidate box (the slow
    reference; one scikit-learn EM per box), the template term over the template's
    samples and the candidate term over all the box's pixels."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    out = np.empty(len(b))
    logp1_t = template.logpdf(template.samples)
    for i, box in enumerate(b):  # the reference is a loop by design
        pix = box_pixels(image, box)
        if len(pix) < 2:
            out[i] = np.inf
            continue
        w, m, c = _fit(pix, template.n_components, seed, reg_covar)
        p2 = MixtureTemplate(w, m, c, pix[:1])
        d = float(np.mean(logp1_t - p2.logpdf(template.samples)))
        if symmetric:
            d += float(np.mean(p2.logpdf(pix) - template.logpdf(pix)))
        out[i] = d
    return out
