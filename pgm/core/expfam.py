r"""Exponential-family beliefs for mean-field variational Bayes.

* :class:`InverseGamma` — a product of independent inverse-Gamma factors
  ``IG(σ²_i | α_i, β_i)``, the belief of a diagonal measurement-noise variable
  (role ``noise``). Natural parameters ``(−α − 1, −β)`` for the sufficient statistics
  ``(log σ², 1/σ²)``; the expectations a VB update needs are
  ``E[1/σ²] = α/β`` and ``E[log σ²] = log β − ψ(α)``.
* :class:`Gaussian` — ``N(mean, cov)``, the belief of a linear-Gaussian state (the
  Kalman / VB adaptive Kalman filter [#sarkka2009]), with information-form natural
  parameters ``(J, h) = (Σ⁻¹, Σ⁻¹ μ)``.

Beliefs are immutable values; updates return new objects.

References
----------
.. [#feng2015] P. Feng, W. Wang, S. M. Naqvi and J. A. Chambers, "Variational Bayesian PHD
   filter with deep learning network updating for multiple human tracking", Proc. Sensor
   Signal Processing for Defence (SSPD), Edinburgh, 2015 (venue inferred; DOI not confirmed).
.. [#sarkka2009] S. Särkkä and A. Nummenmaa, "Recursive noise adaptive Kalman filtering by
   variational Bayesian approximations", IEEE Trans. Automatic Control 54(3), 596–600, 2009.
   doi:10.1109/TAC.2008.2008348
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgm.core.numerics import check_finite_param

__all__ = ["InverseGamma", "Gaussian"]


@dataclass(frozen=True)
class InverseGamma:
    """Independent ``IG(σ²_i | α_i, β_i)``, ``i = 1..d``.

    Parameters
    ----------
    alpha, beta : ndarray, shape (d,)
        Shape and scale, both positive.
    """

    alpha: np.ndarray
    beta: np.ndarray

    def __post_init__(self) -> None:
        a = np.atleast_1d(np.asarray(self.alpha, dtype=float))
        b = np.atleast_1d(np.asarray(self.beta, dtype=float))
        if a.shape != b.shape or a.ndim != 1:
            raise ValueError(f"alpha {a.shape} and beta {b.shape} must be equal 1-D shapes")
        check_finite_param("alpha", a, positive=True)
        check_finite_param("beta", b, positive=True)
        object.__setattr__(self, "alpha", a)
        object.__setattr__(self, "beta", b)

    @classmethod
    def from_sigma(cls, sigma, alpha: float = 10.0) -> InverseGamma:
        """A belief with ``β/α = σ²`` (the plug-in variance) and shape ``alpha``."""
        s = np.atleast_1d(np.asarray(sigma, dtype=float))
        check_finite_param("sigma", s, positive=True)
        a = np.full(s.shape, float(alpha))
        return cls(a, a * s**2)

    @property
    def dim(self) -> int:
        return self.alpha.size

    def natural_params(self) -> tuple[np.ndarray, np.ndarray]:
        """``(−α − 1, −β)`` for the statistics ``(log σ², 1/σ²)``."""
        return -self.alpha - 1.0, -self.beta

    def expected_precision(self) -> np.ndarray:
        """``E[1/σ²] = α/β``."""
        return self.alpha / self.beta

    def expected_log_variance(self) -> np.ndarray:
        """``E[log σ²] = log β − ψ(α)``."""
        from scipy.special import digamma  # imported when used: scipy.special costs ~0.15 s

        return np.log(self.beta) - digamma(self.alpha)

    def r_hat(self) -> np.ndarray:
        """``β/α = 1/E[1/σ²]``: the variance the VB state update plugs in."""
        return self.beta / self.alpha

    def mean(self) -> np.ndarray:
        """``E[σ²] = β/(α − 1)`` (NaN where ``α ≤ 1``)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.alpha > 1, self.beta / (self.alpha - 1), np.nan)

    def cov(self) -> np.ndarray:
        """``Var[σ²]`` on the diagonal, ``β² / ((α − 1)² (α − 2))`` (NaN where ``α ≤ 2``): the
        components are independent."""
        with np.errstate(divide="ignore", invalid="ignore"):
            var = np.where(self.alpha > 2, self.beta ** 2 / ((self.alpha - 1) ** 2
                                                            * (self.alpha - 2)), np.nan)
        return np.diag(var)

    def estimate(self) -> np.ndarray:
        """The point estimate of the belief protocol: the plug-in variance ``β/α`` of the
        VB updates (:meth:`r_hat`; defined for every ``α``, unlike :meth:`mean`)."""
        return self.r_hat()

    #: a density: mass 1
    log_mass = 0.0

    def forget(self, rho: float, alpha_min: float = 0.0) -> InverseGamma:
        """Forgetting prediction ``α̂ = ρα, β̂ = ρβ`` (eq. (18) of [#feng2015]), floored.

        When ``α̂ < alpha_min`` both ``α̂`` and ``β̂`` are multiplied by
        ``alpha_min / α̂`` (flooring ``α`` alone would let ``R̂ → 0``).
        """
        a, b = rho * self.alpha, rho * self.beta
        scale = np.maximum(1.0, alpha_min / a)
        return InverseGamma(a * scale, b * scale)

    def kl(self, other: InverseGamma) -> float:
        """``KL(self ‖ other)`` summed over components (the Gamma KL of the precisions)."""
        a, b, a0, b0 = self.alpha, self.beta, other.alpha, other.beta
        from scipy.special import digamma, gammaln

        return float(np.sum((a - a0) * digamma(a) - gammaln(a) + gammaln(a0)
                            + a0 * (np.log(b) - np.log(b0)) + a * (b0 - b) / b))


class Gaussian:
    """``N(mean, cov)``; ``information()`` gives the natural parameters ``(J, h)``.

    The belief protocol (:mod:`pgm.core.protocol`): ``mean()``, ``cov()``, ``estimate()``
    (the mean), ``log_mass`` (0: a density), ``dim``. The arrays themselves are ``m``
    ``(d,)`` and ``P`` ``(d, d)``, read-only, in the Kalman filter's notation.
    """

    __slots__ = ("m", "P")
    #: a density: mass 1
    log_mass = 0.0

    def __init__(self, mean: np.ndarray, cov: np.ndarray):
        m = np.atleast_1d(np.asarray(mean, dtype=float))
        c = np.atleast_2d(np.asarray(cov, dtype=float))
        if c.shape != (m.size, m.size):
            raise ValueError(f"cov shape {c.shape} does not match mean of length {m.size}")
        check_finite_param("mean", m)
        check_finite_param("cov", c)
        object.__setattr__(self, "m", m)
        object.__setattr__(self, "P", c)

    def __setattr__(self, name: str, value) -> None:
        raise AttributeError(f"Gaussian is immutable: {name!r} cannot be set")

    def __repr__(self) -> str:
        return f"Gaussian(mean={self.m!r}, cov={self.P!r})"

    def __reduce__(self):  # copies and pickles by the constructor (the slots are frozen)
        return (Gaussian, (self.m, self.P))

    @property
    def dim(self) -> int:
        return self.m.size

    def mean(self) -> np.ndarray:
        """The mean ``(d,)``."""
        return self.m

    def cov(self) -> np.ndarray:
        """The covariance ``(d, d)``."""
        return self.P

    def estimate(self) -> np.ndarray:
        """The point estimate of the belief protocol: the mean."""
        return self.m

    def information(self) -> tuple[np.ndarray, np.ndarray]:
        """``(J, h) = (Σ⁻¹, Σ⁻¹ μ)``."""
        J = np.linalg.inv(self.P)
        return J, J @ self.m

    @classmethod
    def from_information(cls, J: np.ndarray, h: np.ndarray) -> Gaussian:
        """Inverse of :meth:`information`."""
        cov = np.linalg.inv(J)
        return cls(cov @ h, cov)

    def __mul__(self, other: Gaussian) -> Gaussian:
        """Product of densities (normalised): natural parameters add."""
        J1, h1 = self.information()
        J2, h2 = other.information()
        return Gaussian.from_information(J1 + J2, h1 + h2)

    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        """``num`` draws, shape ``(num, d)``."""
        return rng.multivariate_normal(self.m, self.P, size=num)

    def log_prob(self, x: np.ndarray) -> np.ndarray:
        """Log-density at ``x`` ``(N, d)``."""
        x = np.atleast_2d(x)
        L = np.linalg.cholesky(self.P)
        u = np.linalg.solve(L, (x - self.m).T)
        return (-0.5 * np.sum(u * u, axis=0) - np.sum(np.log(np.diag(L)))
                - 0.5 * self.dim * np.log(2 * np.pi))

    def kl(self, other: Gaussian) -> float:
        """``KL(self ‖ other)``. Where ``other`` is degenerate (a component known exactly:
        a point prior, a state without process noise), the divergence is that of the two
        restricted to ``other``'s support when ``self`` agrees with it off that support (a
        Kalman posterior of such a prior does), and infinite when it does not."""
        w, V = np.linalg.eigh(0.5 * (other.P + other.P.T))
        scale = max(float(np.abs(w).max(initial=0.0)), float(np.abs(self.P).max(initial=0.0)))
        keep = w > 1e-12 * scale if scale > 0 else np.zeros(w.size, dtype=bool)
        diff = other.m - self.m
        if keep.all():
            J0 = np.linalg.inv(other.P)
            _, ld1 = np.linalg.slogdet(self.P)
            _, ld0 = np.linalg.slogdet(other.P)
            return float(0.5 * (np.trace(J0 @ self.P) + diff @ J0 @ diff - self.dim + ld0 - ld1))
        null = V[:, ~keep]  # directions other holds exactly: self must hold them alike
        tol = 1e-9 * max(scale, 1.0)
        if (np.abs(null.T @ self.P @ null).max() > tol
                or np.abs(null.T @ diff).max() > 1e-9 * max(float(np.abs(other.m).max()), 1.0)):
            return float("inf")
        basis = V[:, keep]
        p1, d = basis.T @ self.P @ basis, basis.T @ diff
        sign, ld1 = np.linalg.slogdet(p1) if keep.any() else (1.0, 0.0)
        if sign <= 0:
            return float("inf")
        w0 = w[keep]
        return float(0.5 * (np.sum(np.diag(p1) / w0) + np.sum(d * d / w0) - keep.sum()
                            + np.sum(np.log(w0)) - ld1))
