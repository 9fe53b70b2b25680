"""Factors: the pieces a tracker is declared from.

A factor has a *scope* (the names of the variables it links) and a *kind* that tells
the engine how inference uses it:

=============== ======================================================================
kind            role in inference
=============== ======================================================================
``prior``       initial belief of a variable (the belief in the first frame)
``transition``  links a variable to its own past values (order 1 or 2)
``likelihood``  links a variable to the current frame / measurements
``coupling``    links two variables in the same frame (parts of one object)
``conjugate``   links a ``noise`` variable to a likelihood it parameterises (VB)
=============== ======================================================================

Each factor is a small object with the few vectorised methods the algorithms need
(``sample``, ``log_prob``, ``log_likelihood``, ...); its parameters live on it and are
listed by :meth:`Factor.params`, which is what a saved model declaration stores.
Every concrete factor class registers itself by name when it is defined, so a JSON
declaration is loaded by looking names up in that registry: loading never executes
code. A user's own factor class is registered as soon as its module is imported.

Arrays: particles have a leading particle axis, ``x`` of shape ``(N, d)``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from .frame import FrameContext
from .numerics import check_finite_param, scratch
from .variable import Variable

__all__ = [
    "Factor", "PriorFactor", "TransitionFactor", "LikelihoodFactor", "CouplingFactor",
    "ConjugateFactor", "GaussianPrior", "LinearGaussianTransition", "AR2Transition",
    "LinearGaussianLikelihood", "factor_from_dict", "registered_factor_types", "KINDS",
]

KINDS = ("prior", "transition", "likelihood", "coupling", "conjugate")
_REGISTRY: dict[str, type[Factor]] = {}


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


class Factor(ABC):  # noqa: B024 - kind base classes declare the abstract methods
    """Base class of all factors.

    Subclasses set the class attribute ``kind`` (via one of the kind base classes),
    take their scope's variable names as the first positional arguments and their
    parameters as keyword arguments, and return those keyword arguments from
    :meth:`params` so that ``type(f)(*f.variables, name=f.name, **f.params())``
    rebuilds an equal factor.
    """

    kind: ClassVar[str] = ""
    #: number of variables in the scope (None: any)
    arity: ClassVar[int | None] = 1

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("abstract", False):
            return
        if cls.kind not in KINDS:
            return
        name = cls.__name__
        other = _REGISTRY.get(name)
        if other is not None and other.__module__ != cls.__module__:
            raise ValueError(
                f"factor type {name!r} is defined twice ({other.__module__} and {cls.__module__})")
        _REGISTRY[name] = cls

    def __init__(self, *variables: str, name: str | None = None) -> None:
        if self.arity is not None and len(variables) != self.arity:
            raise ValueError(
                f"{type(self).__name__} links {self.arity} variable(s), got {len(variables)}: "
                f"{variables}")
        for v in variables:
            if isinstance(v, Variable):
                raise ValueError(f"{type(self).__name__}: give variable names, not objects "
                                 f"(use {v.name!r})")
            if not isinstance(v, str) or not v:
                raise ValueError(f"{type(self).__name__}: variable names must be strings, got {v!r}")
        self.variables: tuple[str, ...] = tuple(variables)
        #: True when the name was made up here (a graph may then disambiguate it)
        self.auto_named = name is None
        self.name = name if name is not None else f"{self.kind}:{'-'.join(variables)}"

    # -- declaration -----------------------------------------------------------------
    def params(self) -> dict[str, Any]:
        """Keyword arguments that rebuild this factor (JSON-ready after conversion)."""
        return {}

    def check(self, variables: dict[str, Variable]) -> None:  # noqa: B027 - optional hook
        """Validate against the graph's variables; raise ``ValueError`` naming the factor."""

    def _check_dim(self, variables: dict[str, Variable], var: str, expected: int, what: str):
        if variables[var].dim != expected:
            raise ValueError(f"factor {self.name!r}: {what} has dimension {expected} but variable "
                             f"{var!r} has dim {variables[var].dim}")

    @property
    def learns(self) -> bool:
        """Whether :meth:`update` does anything (the engine skips the scores otherwise)."""
        return type(self).update is not Factor.update

    def update(self, estimates: dict[str, np.ndarray], scores: dict[str, float],  # noqa: B027
               frame: FrameContext | None = None) -> None:
        """Learn after a frame (adaptive offsets, templates, ...); default: nothing.

        ``estimates`` are the frame's per-variable estimates; ``scores`` the summed
        log-likelihood of each variable's likelihood factors at its estimate; ``frame``
        the frame itself. The engine calls it only for factors whose :attr:`learns` is
        true.
        """

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready declaration ``{"type", "name", "kind", "variables", "params"}``."""
        return {"type": type(self).__name__, "name": self.name, "kind": self.kind,
                "variables": list(self.variables), "params": _jsonable(self.params())}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(self.variables)}, name={self.name!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Factor):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = object.__hash__


def factor_from_dict(d: dict[str, Any]) -> Factor:
    """Rebuild a factor from :meth:`Factor.to_dict` output (a registry lookup, no code)."""
    try:
        type_name = d["type"]
        variables = d["variables"]
    except (KeyError, TypeError) as exc:
        raise ValueError(f"malformed factor declaration {d!r}: missing {exc}") from None
    cls = _REGISTRY.get(type_name)
    if cls is None:
        raise ValueError(
            f"unknown factor type {type_name!r}: import the module that defines it before "
            f"loading (known: {sorted(_REGISTRY)})")
    try:
        return cls(*variables, name=d.get("name"), **d.get("params", {}))
    except TypeError as exc:
        raise ValueError(f"factor {d.get('name')!r} of type {type_name}: {exc}") from None


def registered_factor_types() -> dict[str, type[Factor]]:
    """Name → class of every registered factor type."""
    return dict(_REGISTRY)


# ------------------------------------------------------------------------------------
# kind base classes
# ------------------------------------------------------------------------------------
class PriorFactor(Factor):
    """Initial belief of one variable: the belief in the first frame, before its evidence."""

    kind = "prior"
    abstract = True

    @abstractmethod
    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        """Draw ``num`` values, shape ``(num, d)``."""

    @abstractmethod
    def mean(self) -> np.ndarray:
        """Mean value, shape ``(d,)`` (used to initialise templates)."""


class TransitionFactor(Factor):
    """``p(x_t | x_{t-1}, ..., x_{t-order})`` for one variable."""

    kind = "transition"
    abstract = True
    order: int = 1

    @abstractmethod
    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        """Propagate particles. ``past[0]`` is ``x_{t-1}``, ``past[1]`` is ``x_{t-2}``."""

    def log_prob(self, x: np.ndarray, *past: np.ndarray) -> np.ndarray:
        """``log p(x_t | past)``, shape ``(N,)`` (optional: needed by some proposals)."""
        raise ValueError(f"{type(self).__name__} does not define log_prob()")


class LikelihoodFactor(Factor):
    """``p(z_t | x_t)``: scores all particles of a variable against the current frame."""

    kind = "likelihood"
    abstract = True

    @abstractmethod
    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """Log-likelihood of every particle, shape ``(N,)``, vectorised."""

    #: factors with the same non-None key may be scored together by
    #: ``type(f).log_likelihood_batch`` (one vectorised pass for several variables)
    batch_key = None

    @classmethod
    def log_likelihood_batch(cls, factors: list[LikelihoodFactor], xs: list[np.ndarray],
                             ctx: FrameContext) -> list[np.ndarray]:
        """Score several factors of this class (equal ``batch_key``) in one pass.

        The default scores them one by one; subclasses override it when a joint pass
        is cheaper (e.g. colour histograms of all parts of an object in one frame).
        """
        return [f.log_likelihood(x, ctx) for f, x in zip(factors, xs, strict=True)]

    def initialize(self, ctx: FrameContext, value: np.ndarray) -> None:  # noqa: B027
        """Learn what the factor needs from the first frame (e.g. a template at ``value``).

        Called once by the engine before the first frame is weighted; the default does
        nothing.
        """


class CouplingFactor(Factor):
    """Links two variables of the same frame (parts of one object); used by particle BP.

    Subclasses implement :meth:`map` (deterministic image of particles at the other
    end) and :meth:`log_prob` (the potential, broadcasting); :meth:`propagate` adds
    the factor's noise to :meth:`map` (the default adds none). See
    :mod:`pgm.couplings`.
    """

    kind = "coupling"
    abstract = True
    arity = 2

    def check(self, variables: dict[str, Variable]) -> None:
        if self.variables[0] == self.variables[1]:
            raise ValueError(f"factor {self.name!r}: a coupling links variable "
                             f"{self.variables[0]!r} to itself")

    def other(self, variable: str) -> str:
        """The variable at the other end."""
        a, b = self.variables
        if variable == a:
            return b
        if variable == b:
            return a
        raise ValueError(f"factor {self.name!r} does not link {variable!r}")

    @abstractmethod
    def map(self, x_src: np.ndarray, src: str) -> np.ndarray:
        """Deterministic image ``(N, d_dst)`` of particles ``x_src`` of variable ``src``."""

    @abstractmethod
    def log_prob(self, x_a: np.ndarray, x_b: np.ndarray) -> np.ndarray:
        """``log ψ(x_a, x_b)`` broadcasting over leading axes (``x_a`` is ``variables[0]``)."""

    def propagate(self, rng: np.random.Generator, x_src: np.ndarray, src: str) -> np.ndarray:
        """Message particles from ``src`` to the other end (default: :meth:`map`)."""
        return self.map(x_src, src)


class ConjugateFactor(Factor):
    """Links a ``noise`` variable to the likelihood it parameterises (mean-field VB).

    Scope: ``(noise_variable, target_variable)``. The likelihood factor it
    parameterises (``likelihood``: its name; default every likelihood factor of the
    target) is then updated inside the VB fixed point, not in the weight stage.
    """

    kind = "conjugate"
    abstract = True
    arity = 2

    def __init__(self, noise: str, target: str, *, likelihood: str | None = None,
                 name: str | None = None):
        super().__init__(noise, target, name=name)
        self.likelihood = likelihood

    def params(self) -> dict[str, Any]:
        return {} if self.likelihood is None else {"likelihood": self.likelihood}

    def check(self, variables: dict[str, Variable]) -> None:
        noise, target = self.variables
        if variables[noise].role != "noise":
            raise ValueError(f"factor {self.name!r}: first variable {noise!r} must have role "
                             f"'noise', has {variables[noise].role!r}")
        if noise == target:
            raise ValueError(f"factor {self.name!r}: links variable {noise!r} to itself")


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
        self._sqrt = _sqrt_psd(self.cov, f"factor {self.name!r}: cov")

    def params(self) -> dict[str, Any]:
        return {"mean": self.mean_, "cov": self.cov}

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.mean_.size, "the prior mean")

    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        eps = rng.standard_normal((num, self.mean_.size))
        return self.mean_ + eps @ self._sqrt.T

    def mean(self) -> np.ndarray:
        return self.mean_.copy()

    def log_prob(self, x: np.ndarray) -> np.ndarray:
        """Gaussian log-density (requires a non-singular ``cov``)."""
        from scipy.stats import multivariate_normal

        return np.atleast_1d(multivariate_normal(self.mean_, self.cov).logpdf(x))


class LinearGaussianTransition(TransitionFactor):
    """First-order linear-Gaussian dynamics ``x_t = F x_{t-1} + N(0, Q)``.

    ``p_survive`` is the survival probability used when the variable is a set (a PHD
    intensity's weights are multiplied by it at each prediction).
    """

    order = 1

    def __init__(self, variable: str, *, F, Q, p_survive: float = 1.0,
                 name: str | None = None):
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

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"F": self.F, "Q": self.Q}
        if self.p_survive != 1.0:
            p["p_survive"] = self.p_survive
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.F.shape[0], "F")

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        x = past[0]
        out = x @ self.F.T
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
        return np.atleast_1d(multivariate_normal(np.zeros(len(self.F)), self.Q).logpdf(diff))


class AR2Transition(TransitionFactor):
    r"""Second-order auto-regression with damping (SPEC §1; seed 002, eq. 13).

    .. math::
        X_t = X_{t-1} + a (X_{t-1} - X_{t-2}) + U_t,\quad
        U_t \sim \mathcal N(0, \mathrm{diag}(s^2))

    ``a = 1`` is the paper's model; the default ``a = 0.5`` damps the velocity term
    (SPEC §1 measured 0.65 → 0.75 AUC on FaceOcc1). For a box state
    ``(cx, cy, w, h)``, ``scale_noise > 0`` adds one shared log-scale step per particle
    applied to both ``w`` and ``h`` (indices ``size_indices``), with the size clamped to
    ``scale_clamp`` × ``reference_size``; independent noise on ``w`` and ``h`` is
    possible through ``noise_std`` but destroys accuracy (SPEC §1).

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
    """

    order = 2

    def __init__(self, variable: str, *, noise_std, damping: float = 0.5,
                 scale_noise: float = 0.0, reference_size=None,
                 scale_clamp=(0.5, 2.0), size_indices=(2, 3), name: str | None = None):
        super().__init__(variable, name=name)
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
        if self.scale_noise > 0:
            if self.reference_size is None or self.reference_size.shape != (2,):
                raise ValueError(f"factor {self.name!r}: scale_noise needs reference_size=(w0, h0)")
            check_finite_param(f"{self.name}.reference_size", self.reference_size, positive=True)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"noise_std": self.noise_std, "damping": self.damping}
        if self.scale_noise > 0:
            p.update(scale_noise=self.scale_noise, reference_size=self.reference_size,
                     scale_clamp=list(self.scale_clamp), size_indices=list(self.size_indices))
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.noise_std.size, "noise_std")

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        x1 = past[0]
        x2 = past[1] if len(past) > 1 else past[0]
        x = x1 + self.damping * (x1 - x2) + rng.standard_normal(x1.shape) * self.noise_std
        if self.scale_noise > 0:
            iw, ih = self.size_indices
            step = np.exp(self.scale_noise * rng.standard_normal(x.shape[0]))
            lo, hi = self.scale_clamp
            w = np.clip(x[:, iw] * step, lo * self.reference_size[0], hi * self.reference_size[0])
            s = w / np.maximum(x[:, iw], 1e-12)
            x[:, iw] = w
            x[:, ih] = np.clip(x[:, ih] * s, lo * self.reference_size[1],
                               hi * self.reference_size[1])
        return x

    def log_prob(self, x: np.ndarray, *past: np.ndarray) -> np.ndarray:
        if self.scale_noise > 0 or np.any(self.noise_std == 0):
            raise ValueError(f"factor {self.name!r}: log_prob needs positive noise on every "
                             f"component and no scale step")
        x1 = past[0]
        x2 = past[1] if len(past) > 1 else past[0]
        r = (x - x1 - self.damping * (x1 - x2)) / self.noise_std
        return (-0.5 * np.sum(r * r, axis=1) - np.sum(np.log(self.noise_std))
                - 0.5 * x.shape[1] * np.log(2 * np.pi))


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

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        z = ctx.measurements
        if isinstance(z, dict):
            z = z.get(self.key if self.key is not None else self.variables[0])
        if z is None:
            return np.zeros(x.shape[0])
        y = np.asarray(z, dtype=float).reshape(-1)
        r = y - x @ self.H.T  # (N, k)
        from scipy.linalg import solve_triangular

        u = solve_triangular(self._chol, r.T, lower=True)  # (k, N)
        return self._log_norm - 0.5 * np.sum(u * u, axis=0)
