"""Generic Gaussian factors: a Gaussian prior, linear-Gaussian and damped AR(2)
transitions, and a linear-Gaussian likelihood (the Kalman oracle's model).

References
----------
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param, scratch
from pgm.core.variable import Variable
from pgm.factors.kinds import LikelihoodFactor, PriorFactor, ProposalFactor, TransitionFactor

__all__ = ["GaussianPrior", "LinearGaussianTransition", "AR2Transition",
           "LinearGaussianLikelihood", "LinearGaussianProposal"]


# ------------------------------------------------------------------------------------
# generic concrete factors
# ------------------------------------------------------------------------------------
def _sqrt_psd(cov: np.ndarray, what: str) -> np.ndarray:
    """A matrix ``L`` with ``L L^T = cov`` for a symmetric PSD ``cov`` (zeros allowed)."""
    cov = np.asarray(cov, dtype=float)
    if not np.allclose(cov, cov.T, atol=1e-12):
        raise ValueError(f"{what} must be symmetric")
    if np.count_nonzero(cov - np.diag(np.diag(cov))) == 0:
        diag = np.diag(cov)
        if np.any(diag < 0):
            raise ValueError(f"{what} must be positive semi-definite")
        return np.diag(np.sqrt(diag))
    vals, vecs = np.linalg.eigh(cov)
    if np.any(vals < -1e-10 * max(1.0, float(np.max(np.abs(vals))))):
        raise ValueError(f"{what} must be positive semi-definite")
    return vecs * np.sqrt(np.clip(vals, 0, None))


def _as_cov(value, dim: int | None, what: str) -> np.ndarray:
    """A covariance matrix from a scalar variance, a vector of variances or a matrix."""
    arr = np.asarray(value, dtype=float)
    check_finite_param(what, arr)
    if arr.ndim == 0:
        if dim is None:
            raise ValueError(f"{what}: a scalar needs a known dimension")
        return np.eye(dim) * float(arr)
    if arr.ndim == 1:
        return np.diag(arr)
    if arr.ndim == 2 and arr.shape[0] == arr.shape[1]:
        return arr
    raise ValueError(f"{what} must be a scalar, a vector of variances or a square matrix, "
                     f"got shape {arr.shape}")


class GaussianPrior(PriorFactor):
    """``x_1 ~ N(mean, cov)``; ``cov = 0`` gives a point mass (all particles on ``mean``).

    Parameters
    ----------
    variable : str
    mean : array_like, shape (d,)
    cov : float, array_like (d,) of variances, or (d, d)
    """

    def __init__(self, variable: str, *, mean, cov=0.0, name: str | None = None):
        super().__init__(variable, name=name)
        self.mean_ = np.atleast_1d(np.asarray(mean, dtype=float))
        check_finite_param(f"{self.name}.mean", self.mean_)
        self.cov = _as_cov(cov, self.mean_.size, f"{self.name}.cov")
        if self.cov.shape != (self.mean_.size, self.mean_.size):
            raise ValueError(f"factor {self.name!r}: cov shape {self.cov.shape} does not match "
                             f"mean of length {self.mean_.size}")
        self.__dict__["_sqrt_cache"] = (self.cov, _sqrt_psd(self.cov, f"factor {self.name!r}: cov"))

    @property
    def _sqrt(self) -> np.ndarray:
        """``L`` with ``L Lᵀ = cov`` (recomputed only when ``cov`` was replaced, e.g. by a
        plate birth's scale-aware covariance)."""
        root = self.__dict__.get("_sqrt_cache")
        if root is None or root[0] is not self.cov:
            root = self.__dict__["_sqrt_cache"] = (self.cov, _sqrt_psd(self.cov, "cov"))
        return root[1]

    def params(self) -> dict[str, Any]:
        return {"mean": self.mean_, "cov": self.cov}

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.mean_.size, "the prior mean")

    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        eps = rng.standard_normal((num, self.mean_.size))
        return self.mean_ + eps @ self._sqrt.T

    def mean(self) -> np.ndarray:
        return self.mean_.copy()

    def born_at(self, values: dict[str, float], labels) -> GaussianPrior:
        """The same prior with the mean's components named in ``values`` replaced (a plate
        replica starting on its own box); the covariance is kept."""
        mean = self.mean_.copy()
        labels = list(labels or ())
        for key, val in values.items():
            if key not in labels:
                raise ValueError(f"prior {self.name!r}: no component {key!r} in {labels}")
            mean[labels.index(key)] = float(val)
        return self._with_mean(mean)

    def _with_mean(self, mean: np.ndarray) -> GaussianPrior:
        """This prior with another (finite) mean: the covariance and its square root kept,
        not recomputed (a plate's births re-centre a prior per new target)."""
        if not np.isfinite(mean).all():
            raise ValueError(f"parameter {self.name + '.mean'!r} must be finite, got {mean!r}")
        new = object.__new__(type(self))  # a shallow copy, without copy.copy's reduce protocol
        new.__dict__.update(self.__dict__)
        new.mean_ = mean
        return new

    def log_prob(self, x: np.ndarray) -> np.ndarray:
        """Gaussian log-density (requires a non-singular ``cov``)."""
        from scipy.stats import multivariate_normal

        return np.atleast_1d(multivariate_normal(self.mean_, self.cov).logpdf(x))


class LinearGaussianTransition(TransitionFactor):
    """First-order linear-Gaussian dynamics ``x_t = F x_{t-1} + N(0, Q)``.

    ``p_survive`` is the survival probability used when the variable is a set (a PHD
    intensity's weights are multiplied by it at each prediction).

    **Scale-aware noise**: with ``scale_index`` (the state component holding a log-height
    ``log h``), the noise of the components flagged in ``scaled`` is multiplied by each
    particle's ``h``: ``x_t = F x_{t-1} + D(h) N(0, Q)`` with ``D`` diagonal (1 for the
    other components). ``Q`` is then in units of the target's own height, so one setting
    serves targets near and far from the camera.
    """

    order = 1

    def __init__(self, variable: str, *, F, Q, p_survive: float = 1.0,
                 scale_index: int | None = None, scaled=None, name: str | None = None):
        super().__init__(variable, name=name)
        self.p_survive = float(check_finite_param(f"{variable}.p_survive", p_survive))
        if not 0.0 < self.p_survive <= 1.0:
            raise ValueError(f"factor {self.name!r}: p_survive must be in (0, 1], got {p_survive}")
        self.F = np.atleast_2d(np.asarray(F, dtype=float))
        check_finite_param(f"{self.name}.F", self.F)
        self.Q = _as_cov(Q, self.F.shape[0], f"{self.name}.Q")
        if self.F.shape[0] != self.F.shape[1] or self.Q.shape != self.F.shape:
            raise ValueError(f"factor {self.name!r}: F {self.F.shape} and Q {self.Q.shape} must "
                             f"be square and of equal size")
        self._sqrt = _sqrt_psd(self.Q, f"factor {self.name!r}: Q")
        self.scale_index = None if scale_index is None else int(scale_index)
        self.scaled = None
        if self.scale_index is not None:
            d = self.F.shape[0]
            if not 0 <= self.scale_index < d:
                raise ValueError(f"factor {self.name!r}: scale_index out of range")
            self.scaled = (np.arange(d) != self.scale_index if scaled is None
                           else np.asarray(scaled, dtype=bool).reshape(-1))
            if self.scaled.shape != (d,):
                raise ValueError(f"factor {self.name!r}: scaled needs {d} entries")

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"F": self.F, "Q": self.Q}
        if self.p_survive != 1.0:
            p["p_survive"] = self.p_survive
        if self.scale_index is not None:
            p.update(scale_index=self.scale_index, scaled=self.scaled.tolist())
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.F.shape[0], "F")

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        x = past[0]
        out = x @ self.F.T
        if self.scale_index is not None:
            noise = rng.standard_normal(x.shape) @ self._sqrt.T
            noise[:, self.scaled] *= np.exp(x[:, self.scale_index])[:, None]
            out += noise
            return out
        if x.ndim != 2 or x.shape[0] < 1024:
            out += rng.standard_normal(x.shape) @ self._sqrt.T
            return out
        # many particles: noise into reused buffers. A fresh (N, d) temporary of this size
        # is mmap'd by glibc and page-faulted in on every call, which cost more than the
        # matrix products (same random stream either way)
        noise = scratch(self, "_noise", x.shape)
        mixed = scratch(self, "_mixed", x.shape)
        rng.standard_normal(out=noise)
        np.matmul(noise, self._sqrt.T, out=mixed)
        out += mixed
        return out

    def log_prob(self, x: np.ndarray, *past: np.ndarray) -> np.ndarray:
        from scipy.stats import multivariate_normal

        diff = x - past[0] @ self.F.T
        if self.scale_index is not None:  # D(h)^-1 diff ~ N(0, Q), Jacobian: -sum log h
            log_h = past[0][:, self.scale_index]
            diff = diff.copy()
            diff[:, self.scaled] *= np.exp(-log_h)[:, None]
            return (multivariate_normal(np.zeros(len(self.F)), self.Q, allow_singular=True)
                    .logpdf(diff) - self.scaled.sum() * log_h)
        return np.atleast_1d(multivariate_normal(np.zeros(len(self.F)), self.Q).logpdf(diff))

    def log_prob_columns(self, x: np.ndarray, columns, *past: np.ndarray) -> np.ndarray:
        """The marginal ``N(x[c]; (F x_{t-1})[c], Q[c, c])`` of components ``c``; they must
        be drawn independently of the others (``Q[c, rest] = 0``; no scale index)."""
        if columns is None or sorted(columns) == list(range(x.shape[1])):
            return self.log_prob(x, *past)
        from scipy.stats import multivariate_normal

        c = list(columns)
        rest = [i for i in range(len(self.F)) if i not in c]
        if self.scale_index is not None or np.any(self.Q[np.ix_(c, rest)] != 0):
            raise ValueError(f"factor {self.name!r}: components {c} are not drawn "
                             f"independently of the others (Q couples them, or a scale "
                             f"index scales them)")
        diff = x[:, c] - (past[0] @ self.F.T)[:, c]
        return np.atleast_1d(multivariate_normal(np.zeros(len(c)), self.Q[np.ix_(c, c)])
                             .logpdf(diff))


class AR2Transition(TransitionFactor):
    r"""Second-order auto-regression with damping (eq. (13) of Zhang & Kang [#zhang2015]).

    .. math::
        X_t = X_{t-1} + a (X_{t-1} - X_{t-2}) + U_t,\quad
        U_t \sim \mathcal N(0, \mathrm{diag}(s^2))

    ``a = 1`` is the paper's model; the default ``a = 0.5`` damps the velocity term
    (measured on FaceOcc1 with a one-node colour filter: success AUC 0.65 undamped, 0.75
    damped). For a box state ``(cx, cy, w, h)``, ``scale_noise > 0`` adds one shared
    log-scale step per particle applied to both ``w`` and ``h`` (indices
    ``size_indices``), with the size clamped to ``scale_clamp`` × ``reference_size``;
    independent noise on ``w`` and ``h`` is possible through ``noise_std`` but destroys
    accuracy (one-node FaceOcc1: AUC 0.65 → 0.44 at a size noise of only 0.005 × size).

    Parameters
    ----------
    variable : str
    noise_std : array_like, shape (d,)
        Standard deviations ``s`` of ``U_t``.
    damping : float
        ``a`` in the equation, in ``[0, 1]``.
    scale_noise : float
        Standard deviation of the shared log-scale step (0: fixed size).
    reference_size : array_like (2,), optional
        ``(w_0, h_0)`` for the clamp; required when ``scale_noise > 0``.
    scale_clamp : (float, float)
    size_indices : (int, int)
    jump_prob, jump_scale : float
        A heavy-tailed step for fast motion: with probability ``jump_prob`` a particle's
        noise is ``jump_scale`` times wider (a two-component Gaussian mixture; 0: none).
        The narrow component keeps the particles dense on slow motion, the wide one
        keeps hypotheses at the distances a fast object covers in one frame.
    relative : bool
        Scale-aware noise: ``noise_std`` is in units of each particle's own box height
        (component ``size_indices[1]`` of ``x_{t-1}``), and the log-scale step is not
        clamped to a reference size — one setting for a person near the camera and one
        far away (plate models). Default False (pixels).
    reappear_prob : float
        A re-appearance: with this probability per frame the position components
        (``position_indices``) are drawn uniformly over ``region`` instead (the object was
        lost from view and comes back anywhere; 0: never). A step longer than four
        standard deviations of the widest noise component is a re-appearance: it carries
        no velocity into the next frame (the AR(2) term restarts from rest), so a
        particle that re-appeared does not fly on. With a re-appearance a proposal near
        an appearance peak anywhere in ``region`` stays importance-correct
        (:class:`~pgm.observation.appearance.redetection.RedetectionProposal`).
    reappear_drawn : bool
        Whether :meth:`sample` draws the re-appearances (True, the default) or leaves
        them to a proposal (False: they stay in the density, :meth:`log_prob`, and a
        proposal puts particles where the object may have come back, its importance
        weights carrying the prior odds ``reappear_prob / area``). Drawn at the prior
        rate, a re-appearance is one particle in a hundred standing for a prior mass of
        ``reappear_prob``: when it lands on a distractor whose likelihood beats the
        cloud's it takes the posterior whatever the prior odds (with ``reappear_prob``
        0.001 the single-object default with re-detection lost Biker and Tiger1 that
        way: AUC 0.302 and 0.676 over eight seeds, 0.323 and 0.690 with none drawn).
        Without a proposal nothing then samples a re-appearance: the density alone
        brings no particle back.
    region : (x0, y0, x1, y1), optional
        Where an object may re-appear (the frame, in pixels); required when
        ``reappear_prob > 0``.
    position_indices : (int, int)
    """

    order = 2

    def __init__(self, variable: str, *, noise_std, damping: float = 0.5,
                 scale_noise: float = 0.0, reference_size=None,
                 scale_clamp=(0.5, 2.0), size_indices=(2, 3), jump_prob: float = 0.0,
                 jump_scale: float = 1.0, relative: bool = False, reappear_prob: float = 0.0,
                 region=None, position_indices=(0, 1), reappear_drawn: bool = True,
                 name: str | None = None):
        super().__init__(variable, name=name)
        self.reappear_prob = float(check_finite_param(f"{self.name}.reappear_prob",
                                                      reappear_prob, nonneg=True))
        if self.reappear_prob >= 1:
            raise ValueError(f"factor {self.name!r}: reappear_prob must be in [0, 1)")
        if reappear_drawn not in (True, False, 0, 1):
            raise ValueError(f"factor {self.name!r}: reappear_drawn is true or false, got "
                             f"{reappear_drawn!r}")
        self.reappear_drawn = bool(reappear_drawn)
        self.position_indices = tuple(int(i) for i in position_indices)
        self.region = None if region is None else np.asarray(region, dtype=float).reshape(-1)
        if self.reappear_prob > 0:
            if self.region is None or self.region.shape != (2 * len(self.position_indices),):
                raise ValueError(f"factor {self.name!r}: reappear_prob needs region=(x0, y0, "
                                 f"x1, y1), the area where the object may re-appear")
            check_finite_param(f"{self.name}.region", self.region)
            k = len(self.position_indices)
            if np.any(self.region[k:] <= self.region[:k]):
                raise ValueError(f"factor {self.name!r}: region must have x1 > x0 and y1 > y0, "
                                 f"got {self.region.tolist()}")
        if not isinstance(relative, (bool, np.bool_)):
            raise ValueError(f"factor {self.name!r}: relative must be true or false, got "
                             f"{relative!r}")
        self.relative = bool(relative)
        self.jump_prob = float(check_finite_param(f"{self.name}.jump_prob", jump_prob,
                                                  nonneg=True))
        if self.jump_prob >= 1:
            raise ValueError(f"factor {self.name!r}: jump_prob must be in [0, 1)")
        self.jump_scale = float(check_finite_param(f"{self.name}.jump_scale", jump_scale,
                                                   positive=True))
        self.noise_std = np.atleast_1d(np.asarray(noise_std, dtype=float))
        check_finite_param(f"{self.name}.noise_std", self.noise_std, nonneg=True)
        self.damping = float(check_finite_param(f"{self.name}.damping", damping))
        if not 0.0 <= self.damping <= 1.0:
            raise ValueError(f"factor {self.name!r}: damping must be in [0, 1], got {damping}")
        self.scale_noise = float(check_finite_param(f"{self.name}.scale_noise", scale_noise,
                                                    nonneg=True))
        self.scale_clamp = tuple(float(s) for s in scale_clamp)
        if not 0 < self.scale_clamp[0] <= 1.0 <= self.scale_clamp[1]:
            raise ValueError(f"factor {self.name!r}: scale_clamp must satisfy 0 < lo <= 1 <= hi")
        self.size_indices = tuple(int(i) for i in size_indices)
        self.reference_size = (None if reference_size is None
                               else np.asarray(reference_size, dtype=float))
        if self.scale_noise > 0 and not self.relative:
            if self.reference_size is None or self.reference_size.shape != (2,):
                raise ValueError(f"factor {self.name!r}: scale_noise needs reference_size=(w0, h0)")
            check_finite_param(f"{self.name}.reference_size", self.reference_size, positive=True)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"noise_std": self.noise_std, "damping": self.damping}
        if self.scale_noise > 0:
            p.update(scale_noise=self.scale_noise, reference_size=self.reference_size,
                     scale_clamp=list(self.scale_clamp), size_indices=list(self.size_indices))
        if self.jump_prob > 0:
            p.update(jump_prob=self.jump_prob, jump_scale=self.jump_scale)
        if self.relative:
            p.update(relative=True, size_indices=list(self.size_indices))
            p.pop("reference_size", None)
            p.pop("scale_clamp", None)
        if self.reappear_prob > 0:
            p.update(reappear_prob=self.reappear_prob, region=self.region,
                     position_indices=list(self.position_indices))
            if not self.reappear_drawn:
                p["reappear_drawn"] = False
        return p

    def _step(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """The velocity term ``a (x_{t-1} - x_{t-2})``; with re-appearances, zero for a
        particle whose last position step exceeded four widest standard deviations."""
        d = self.damping * (x1 - x2)
        if self.reappear_prob == 0:
            return d
        pos = list(self.position_indices)
        reach = 4.0 * self.noise_std[pos] * (self.jump_scale if self.jump_prob > 0 else 1.0)
        reach = np.broadcast_to(reach, (x1.shape[0], len(pos)))
        if self.relative:
            reach = reach * np.maximum(x1[:, self.size_indices[1]], 1e-6)[:, None]
        restart = np.any(np.abs(x1[:, pos] - x2[:, pos]) > reach, axis=1)
        return np.where(restart[:, None], 0.0, d)

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.noise_std.size, "noise_std")

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        x1 = past[0]
        x2 = past[1] if len(past) > 1 else past[0]
        noise = rng.standard_normal(x1.shape) * self.noise_std
        if self.relative:
            noise *= np.maximum(x1[:, self.size_indices[1]], 1e-6)[:, None]
        if self.jump_prob > 0:
            noise *= np.where(rng.random(x1.shape[0]) < self.jump_prob, self.jump_scale,
                              1.0)[:, None]
        x = x1 + self._step(x1, x2) + noise
        if self.reappear_prob > 0 and self.reappear_drawn:
            pos = list(self.position_indices)
            k = len(pos)
            back = rng.random(x1.shape[0]) < self.reappear_prob
            x[np.ix_(back, pos)] = (self.region[:k] + rng.random((int(back.sum()), k))
                                    * (self.region[k:] - self.region[:k]))
        if self.scale_noise > 0:
            iw, ih = self.size_indices
            step = np.exp(self.scale_noise * rng.standard_normal(x.shape[0]))
            if self.relative:
                x[:, iw] = np.maximum(x[:, iw], 1e-6) * step
                x[:, ih] = np.maximum(x[:, ih], 1e-6) * step
                return x
            lo, hi = self.scale_clamp
            w = np.clip(x[:, iw] * step, lo * self.reference_size[0], hi * self.reference_size[0])
            s = w / np.maximum(x[:, iw], 1e-12)
            x[:, iw] = w
            x[:, ih] = np.clip(x[:, ih] * s, lo * self.reference_size[1],
                               hi * self.reference_size[1])
        return x

    def log_prob(self, x: np.ndarray, *past: np.ndarray) -> np.ndarray:
        if self.relative or self.scale_noise > 0 or np.any(self.noise_std == 0):
            raise ValueError(f"factor {self.name!r}: log_prob needs positive noise in pixels on "
                             f"every component and no scale step")
        return self._log_prob(x, list(range(x.shape[1])), *past)

    def _log_prob(self, x: np.ndarray, c: list[int], *past: np.ndarray) -> np.ndarray:
        """The AR(2) density of components ``c``, mixed with the uniform re-appearance."""
        step = self._log_prob_ar2(x, c, *past)
        if self.reappear_prob == 0:
            return step
        pos = list(self.position_indices)
        if not set(c) <= set(pos):
            raise ValueError(f"factor {self.name!r}: with re-appearances the density is that "
                             f"of position components {pos} only, not of {c}")
        k = len(pos)
        lo, hi = self.region[:k], self.region[k:]
        j = [pos.index(i) for i in c]
        inside = np.all((x[:, c] >= lo[j]) & (x[:, c] <= hi[j]), axis=1)
        log_u = np.where(inside, -float(np.sum(np.log(hi[j] - lo[j]))), -np.inf)
        return np.logaddexp(np.log1p(-self.reappear_prob) + step,
                            np.log(self.reappear_prob) + log_u)

    def log_prob_columns(self, x: np.ndarray, columns, *past: np.ndarray) -> np.ndarray:
        """The marginal density of components ``columns`` with positive noise outside the
        size components of the scale step (e.g. the centre): their damped step with the
        jump mixture (its jump shared by the components), in pixels or in box heights
        (``relative``); the scale step acts on the sizes alone, independently."""
        if columns is None or sorted(columns) == list(range(x.shape[1])):
            return self.log_prob(x, *past)
        c = list(columns)
        sizes = set(self.size_indices) if self.scale_noise > 0 else set()
        if any(self.noise_std[i] == 0 or i in sizes for i in c):
            raise ValueError(f"factor {self.name!r}: components {c} need positive noise and "
                             f"must not be sizes of the scale step")
        return self._log_prob(x, c, *past)

    def _log_prob_ar2(self, x: np.ndarray, c: list[int], *past: np.ndarray) -> np.ndarray:
        x1 = past[0]
        x2 = past[1] if len(past) > 1 else past[0]
        std = np.broadcast_to(self.noise_std[c], (x.shape[0], len(c)))
        if self.relative:
            std = std * np.maximum(x1[:, self.size_indices[1]], 1e-6)[:, None]
        r = (x[:, c] - x1[:, c] - self._step(x1, x2)[:, c]) / std
        d = len(c)
        narrow = (-0.5 * np.sum(r * r, axis=1) - np.sum(np.log(std), axis=1)
                  - 0.5 * d * np.log(2 * np.pi))
        if self.jump_prob == 0:
            return narrow
        k = self.jump_scale
        wide = narrow + 0.5 * np.sum(r * r, axis=1) * (1 - 1 / k ** 2) - d * np.log(k)
        return np.logaddexp(np.log1p(-self.jump_prob) + narrow,
                            np.log(self.jump_prob) + wide)


class AveragedVelocityTransition(TransitionFactor):
    r"""Constant velocity with the velocity averaged over the last ``window`` steps.

    .. math::
        X_t = X_{t-1} + \frac{1}{k}(X_{t-1} - X_{t-1-k}) + U_t,\quad
        U_t \sim \mathcal N(0, \mathrm{diag}(s^2))

    ``k = window`` (3: Wang, Yin & Man's "constant velocity averaged over the last three
    differences" baseline; 1: plain constant velocity). With ``relative=True`` the
    noise is in units of each particle's box height (component ``size_indices[1]``) and
    a log-scale step ``scale_noise`` is shared by ``w`` and ``h``. The transition's order
    is ``window + 1``; at a track's birth the history holds the birth box, so the
    velocity starts at zero.

    Parameters
    ----------
    variable : str
    noise_std : array_like (d,)
    window : int
    scale_noise : float
    relative : bool
    size_indices : (int, int)
    """

    def __init__(self, variable: str, *, noise_std, window: int = 3, scale_noise: float = 0.0,
                 relative: bool = False, size_indices=(2, 3), name: str | None = None):
        super().__init__(variable, name=name)
        if isinstance(window, bool) or int(window) != window or window < 1:
            raise ValueError(f"factor {self.name!r}: window must be a positive integer, got "
                             f"{window!r}")
        self.window = int(window)
        self.order = self.window + 1
        self.noise_std = np.atleast_1d(np.asarray(noise_std, dtype=float))
        check_finite_param(f"{self.name}.noise_std", self.noise_std, nonneg=True)
        self.scale_noise = float(check_finite_param(f"{self.name}.scale_noise", scale_noise,
                                                    nonneg=True))
        self.relative = bool(relative)
        self.size_indices = tuple(int(i) for i in size_indices)

    def params(self) -> dict[str, Any]:
        return {"noise_std": self.noise_std, "window": self.window,
                "scale_noise": self.scale_noise, "relative": self.relative,
                "size_indices": list(self.size_indices)}

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.noise_std.size, "noise_std")

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        x1 = past[0]
        xk = past[self.window] if len(past) > self.window else past[-1]
        noise = rng.standard_normal(x1.shape) * self.noise_std
        iw, ih = self.size_indices
        if self.relative:
            noise *= np.maximum(x1[:, ih], 1e-6)[:, None]
        x = x1 + (x1 - xk) / self.window + noise
        if self.scale_noise > 0:
            step = np.exp(self.scale_noise * rng.standard_normal(x.shape[0]))
            x[:, iw] = np.maximum(x[:, iw], 1e-6) * step
            x[:, ih] = np.maximum(x[:, ih], 1e-6) * step
        return x


class LinearGaussianLikelihood(LikelihoodFactor):
    """``y_t = H x_t + N(0, R)`` with ``y_t`` the frame's ``measurements`` (one vector).

    The frame context's ``measurements`` is an array of shape ``(k,)`` (or ``(1, k)``),
    or a dict from which the entry ``key`` (default: the variable's name) is read, so
    that several variables can each have their own observation. A frame with no
    measurement for the factor carries no evidence (the factor returns zeros), which
    is how missing observations are expressed.
    """

    def __init__(self, variable: str, *, H, R, key: str | None = None,
                 name: str | None = None):
        super().__init__(variable, name=name)
        self.key = key
        self.H = np.atleast_2d(np.asarray(H, dtype=float))
        check_finite_param(f"{self.name}.H", self.H)
        self.R = _as_cov(R, self.H.shape[0], f"{self.name}.R")
        if self.R.shape != (self.H.shape[0],) * 2:
            raise ValueError(f"factor {self.name!r}: R {self.R.shape} does not match H "
                             f"{self.H.shape}")
        try:
            self._chol = np.linalg.cholesky(self.R)
        except np.linalg.LinAlgError:
            raise ValueError(f"factor {self.name!r}: R must be positive definite") from None
        self._log_norm = (-0.5 * self.H.shape[0] * np.log(2 * np.pi)
                          - np.sum(np.log(np.diag(self._chol))))

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"H": self.H, "R": self.R}
        if self.key is not None:
            p["key"] = self.key
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.H.shape[1], "H's column count")

    def noise_residuals(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray | None:
        """The conjugate contract of VB over this factor's noise
        (:mod:`pgm.inference.vb`): the residuals ``y − H x`` ``(N, k)``, whose components
        carry independent zero-mean Gaussian noise of the noise variable's variances; None
        on a frame without a measurement."""
        z = self.measurement(ctx)
        return None if z is None else z - x @ self.H.T

    def measurement(self, ctx: FrameContext) -> np.ndarray | None:
        """This frame's measurement ``(k,)`` of this factor (None: the frame has none);
        one of another length than ``H``'s rows, or not finite, is a ``ValueError`` naming
        the factor and the frame (a frame without a measurement is ``measurements=None``,
        or a dict without this factor's key)."""
        z = ctx.measurements
        if isinstance(z, dict):
            z = z.get(self.key if self.key is not None else self.variables[0])
        if z is None:
            return None
        z = np.asarray(z, dtype=float).reshape(-1)
        if z.size != self.H.shape[0] or not np.isfinite(z).all():
            what = (f"has {z.size} components where H has {self.H.shape[0]} rows"
                    if z.size != self.H.shape[0] else f"is not finite ({z.tolist()})")
            raise ValueError(f"factor {self.name!r}: the measurement of frame {ctx.index} "
                             f"{what} (a frame without one: measurements=None)")
        return z

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        r = self.noise_residuals(x, ctx)  # (N, k)
        if r is None:
            return np.zeros(x.shape[0])
        from scipy.linalg import solve_triangular

        u = solve_triangular(self._chol, r.T, lower=True)  # (k, N)
        return self._log_norm - 0.5 * np.sum(u * u, axis=0)


class LinearGaussianProposal(ProposalFactor):
    r"""The Gaussian proposal of a linear-Gaussian step, ``x_t = F x_{t-1} + N(0, Q)``
    observed as ``y_t = H x_t + N(0, R)``:

    .. math::
        q(x_t \mid x_{t-1}, y_t) = \mathcal N\big(\Sigma (Q^{-1} F x_{t-1}
            + H^\top R^{-1} y_t),\ \Sigma\big),\qquad
        \Sigma = (Q^{-1} + H^\top R^{-1} H)^{-1},

    the *locally optimal* proposal (Doucet, Godsill & Andrieu 2000): with it the
    incremental weight is ``p(y_t | x_{t-1})`` whatever ``x_t`` was drawn. Given ``F``
    and ``Q`` only (``H`` omitted), or with ``inflate > 1``, it is a plain Gaussian
    random walk around ``F x_{t-1}`` of covariance ``inflate · Q`` — a broad, wrong but
    valid proposal. A frame with no measurement (``key``, as
    :class:`LinearGaussianLikelihood`) proposes from ``N(F x_{t-1}, inflate · Q)``.
    """

    def __init__(self, variable: str, *, F, Q, H=None, R=None, inflate: float = 1.0,
                 key: str | None = None, fraction: float = 1.0, name: str | None = None):
        super().__init__(variable, fraction=fraction, name=name)
        self.F = np.atleast_2d(np.asarray(F, dtype=float))
        d = self.F.shape[0]
        self.Q = _as_cov(Q, d, f"{self.name}.Q")
        self.inflate = check_finite_param(f"{self.name}.inflate", inflate, positive=True)
        self.key = key
        self.H = None if H is None else np.atleast_2d(np.asarray(H, dtype=float))
        self.R = None if R is None else _as_cov(R, self.H.shape[0], f"{self.name}.R")
        q = self.inflate * self.Q
        if self.H is not None:
            info = np.linalg.inv(q) + self.H.T @ np.linalg.solve(self.R, self.H)
            self._cov = np.linalg.inv(info)
            self._cov = 0.5 * (self._cov + self._cov.T)
        self._q = q

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"F": self.F, "Q": self.Q, "fraction": self.fraction}
        if self.H is not None:
            p.update(H=self.H, R=self.R)
        if self.inflate != 1.0:
            p["inflate"] = self.inflate
        if self.key is not None:
            p["key"] = self.key
        return p

    def _moments(self, ctx: FrameContext, x_prev: np.ndarray):
        mean = x_prev @ self.F.T
        z = ctx.measurements
        if isinstance(z, dict):
            z = z.get(self.key if self.key is not None else self.variables[0])
        if self.H is None or z is None:
            return mean, self._q
        y = np.asarray(z, dtype=float).reshape(-1)
        m = (mean @ np.linalg.inv(self._q).T + y @ np.linalg.solve(self.R, self.H)) @ self._cov.T
        return m, self._cov

    def sample(self, rng: np.random.Generator, ctx: FrameContext,
               *past: np.ndarray) -> np.ndarray:
        mean, cov = self._moments(ctx, np.asarray(past[0], dtype=float))
        return mean + rng.standard_normal(mean.shape) @ np.linalg.cholesky(cov).T

    def log_prob(self, x: np.ndarray, ctx: FrameContext, *past: np.ndarray) -> np.ndarray:
        mean, cov = self._moments(ctx, np.asarray(past[0], dtype=float))
        chol = np.linalg.cholesky(cov)
        u = np.linalg.solve(chol, (np.asarray(x, dtype=float) - mean).T)
        return (-0.5 * np.sum(u * u, axis=0) - np.sum(np.log(np.diag(chol)))
                - 0.5 * cov.shape[0] * np.log(2 * np.pi))
