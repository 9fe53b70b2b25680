r"""Regularised resampling of a PHD intensity: each target's particles spread again by a
kernel of their own posterior.

Resampling copies the particles the corrector favoured; when the transition's noise is
small against the posterior's spread (a walker's velocity noise over one frame), the
copies are not spread apart again and a target's cloud shrinks onto a few points
(sample impoverishment). A regularised particle filter (Musso, Oudjane & Le Gland
[#musso2001]) draws each resampled particle from a kernel around its ancestor instead;
with Liu & West's shrinkage [#liu2001] the kernel keeps the cloud's mean and covariance:

.. math::
    x' = a\,x + (1 - a)\,\mu_z + h\,A_z\,\varepsilon,\qquad a = \sqrt{1 - h^2},\quad
    A_z A_z^\top = \Sigma_z,\quad \varepsilon \sim N(0, I),

so that ``E[x'] = μ_z`` and ``Cov[x'] = a² Σ_z + h² Σ_z = Σ_z``.

On an intensity the posterior of one target is the share of the particles a measurement
``z`` explains: the corrector's association weights ``ω_jz`` (those the extraction
averages), so ``μ_z = Σ_j ω_jz x_j / W_z`` and ``Σ_z`` their weighted covariance. A
particle is moved by measurement ``z``'s kernel when ``z`` explains more than half of its
posterior weight; the rest (targets missed this frame, mass no measurement claims) are
left as they are. The bandwidth is the Gaussian kernel's optimum for the ``N_z`` particles
the measurement's share receives, ``h = (4 / ((d + 2) N_z))^{1/(d+4)}`` (Silverman's rule
[#silverman1986], ``d`` the state's dimension): nothing is set per scene.

References
----------
.. [#musso2001] C. Musso, N. Oudjane and F. Le Gland, "Improving regularised particle
   filters", in A. Doucet, N. de Freitas and N. Gordon (eds.), *Sequential Monte Carlo
   Methods in Practice*, Springer, 2001.
.. [#liu2001] J. Liu and M. West, "Combined parameter and state estimation in
   simulation-based filtering", in the same volume, 2001.
.. [#silverman1986] B. W. Silverman, *Density Estimation for Statistics and Data
   Analysis*, Chapman & Hall, 1986.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

__all__ = ["kernel_bandwidth", "measurement_moments", "regularise"]


def kernel_bandwidth(n: np.ndarray | float, d: int) -> np.ndarray:
    """The Gaussian kernel's optimal bandwidth ``(4 / ((d + 2) n))^{1/(d+4)}`` for ``n``
    particles (at least one) in ``d`` dimensions."""
    n = np.maximum(np.asarray(n, dtype=float), 1.0)
    return (4.0 / ((d + 2) * n)) ** (1.0 / (d + 4))


def measurement_moments(x: np.ndarray, omega: np.ndarray, W: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(W (M,), mu (M, d), cov (M, d, d))``: each measurement's share of the particles
    ``x`` ``(N, d)`` under the association weights ``omega`` ``(N, M)`` — its mass, its
    weighted mean and covariance (a measurement with no share: zeros; ``W``: the column
    sums of ``omega`` when already known). One product of
    the particles' first and second powers with ``omega``; the states are taken relative
    to one of them first, so the covariance loses no precision to large coordinates."""
    n, d = x.shape
    W = omega.sum(axis=0) if W is None else np.asarray(W, dtype=float)
    ref = x[0]
    xc = np.ascontiguousarray((x - ref).T)  # (d, N)
    iu = _upper(d)
    mom = np.concatenate([xc, xc[iu[0]] * xc[iu[1]]]) @ omega  # (d + d(d+1)/2, M)
    has = W > 0
    mom[:, has] /= W[has]
    mom[:, ~has] = 0.0
    mu_c = mom[:d].T  # (M, d)
    cov = np.empty((len(W), d, d))
    cov[:, iu[0], iu[1]] = mom[d:].T - mu_c[:, iu[0]] * mu_c[:, iu[1]]
    cov[:, iu[1], iu[0]] = cov[:, iu[0], iu[1]]
    return W, mu_c + ref, cov


@functools.cache
def _upper(d: int) -> tuple[np.ndarray, np.ndarray]:
    return np.triu_indices(d)


def _roots(cov: np.ndarray) -> np.ndarray:
    """``A`` with ``A Aᵀ = cov`` for each of a batch of covariances: the Cholesky factor
    of ``cov`` plus ``10⁻⁹`` of its mean variance on the diagonal (a spread of one
    particle is zero), or, if rounding left one not positive, the eigenvectors scaled by
    the roots of the eigenvalues clipped at 0."""
    d = cov.shape[-1]
    ridge = 1e-9 * np.abs(np.trace(cov, axis1=1, axis2=2)) / d + 1e-300
    try:
        return np.linalg.cholesky(cov + ridge[:, None, None] * np.eye(d))
    except np.linalg.LinAlgError:
        vals, vecs = np.linalg.eigh(cov)
        return vecs * np.sqrt(np.clip(vals, 0.0, None))[:, None, :]


def regularise(rng: np.random.Generator, x: np.ndarray, idx: np.ndarray,
               last: dict[str, Any], budget: int, mass: float) -> np.ndarray:
    """The resampled particles ``x[idx]`` moved by their measurements' kernels (see the
    module's docstring). ``x`` ``(N, d)``: the persistent particles the corrector
    weighed, ``last``: its pieces (``omega`` ``(N, M)``, posterior weights ``w`` ``(N,)``,
    and ``W`` ``(M,)`` if known); ``budget`` particles were drawn in all from an intensity
    of mass ``mass``. Returns a new array; ``x[idx]`` itself when no measurement explains
    any particle."""
    out = x.take(idx, axis=0)
    omega = last.get("omega") if last is not None else None
    if omega is None or omega.ndim != 2 or omega.shape[0] != x.shape[0] or not omega.shape[1]:
        return out
    n, d = x.shape
    m = omega.shape[1]
    owner = omega.argmax(axis=1)
    claimed = omega[np.arange(n), owner] > 0.5 * np.asarray(last["w"], dtype=float)
    known = last.get("W")
    W, mu, cov = measurement_moments(x, omega, known if np.shape(known) == (m,) else None)
    claimed &= W.take(owner) > 0
    if not claimed.any():
        return out
    h = kernel_bandwidth(budget * W / max(mass, 1e-300), d)
    used = np.bincount(owner[claimed], minlength=m) > 0  # kernels of these only
    # one more "measurement" m for the particles no measurement claims: a = 1, no kernel
    A = np.zeros((m + 1, d, d))
    A[:m][used] = _roots(cov[used]) * h[used, None, None]  # the kernel's root, h A_z
    a = np.ones(m + 1)
    a[:m] = np.sqrt(1.0 - h * h)
    shift = np.zeros((m + 1, d))
    shift[:m] = (1.0 - a[:m, None]) * mu
    z = np.where(claimed, owner, m).take(idx)
    eps = rng.standard_normal((d, len(z)))
    Az = A[z]  # (budget, d, d)
    out *= a[z][:, None]
    out += shift[z]
    for j in range(d):  # A_z ε over the few state components (not over particles)
        out += Az[:, :, j] * eps[j][:, None]
    return out
