"""The GPDM itself: settings, kernels, the learned model and its storage.

See :mod:`pgm.dynamics.gpdm` for the model, its fixes and where it departs from the
paper.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pgm.core.errors import InputError, one_line

FORMAT = "pgm-gpdm"
VERSION = 1
#: box (lower, upper) of each free hyper-parameter other than the two noise variances
#: (whose lower bound is their floor and upper bound :data:`NOISE_UPPER`)
HYPER_BOUNDS = {"alpha1": (1e-3, 1e3), "alpha2": (1e-2, 10.0), "alpha3": (1e-4, 1e2),
                "beta1": (1e-2, 10.0)}
#: upper bound of both noise variances (the data and the latent have unit scale)
NOISE_UPPER = 10.0
#: (α₁, α₂, α₃) held fixed when :attr:`GPDMSettings.fix_dynamics` is on
FIXED_DYNAMICS = (1.0, 1.0, 0.1)
_DT = torch.float64
#: ways of fixing the latent scale (:attr:`GPDMSettings.latent_scale`)
LATENT_SCALES = ("unit", "prior")
_ARRAYS = ("X", "Y", "lengths", "alpha", "beta", "y_mean", "y_std")


# --------------------------------------------------------------------------- settings


def _int_at_least(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"parameter {name!r} must be an integer >= {low}, got {value!r}")
    return int(value)


def _float_in(name: str, value: Any, low: float, high: float, *, open_low: bool = True
              ) -> float:
    if isinstance(value, bool):
        raise ValueError(f"parameter {name!r} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"parameter {name!r} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"parameter {name!r} must be finite, got {value!r}")
    if (v <= low if open_low else v < low) or v > high:
        bracket = "(" if open_low else "["
        raise ValueError(f"parameter {name!r} must be in {bracket}{low}, {high}], got {value!r}")
    return v


def _bool(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"parameter {name!r} must be True or False, got {value!r}")
    return bool(value)


@dataclass(frozen=True)
class GPDMSettings:
    """Settings of GPDM learning and prediction (typed and validated; JSON-able).

    Attributes
    ----------
    latent_dim : int
        Latent dimension ``d`` (the paper's: 2).
    obs_noise_floor : float
        Floor of the observation noise variance ``β₂⁻¹``, relative to the variance of
        the standardised observations (1), in (0, 1].
    dyn_noise_floor : float
        Floor of the dynamics noise variance ``α₄⁻¹``, relative to the initial latent
        mean square (1), in (0, 1].
    latent_scale : {"unit", "prior"}
        ``"unit"``: the latent's mean square is held at 1 (a reparametrisation);
        ``"prior"``: an ``N(0, I)`` prior on every latent point (see the module notes:
        it does not stop the shrinking by itself).
    fix_dynamics : bool
        Hold ``α₁..α₄`` at :data:`FIXED_DYNAMICS`.
    balanced : bool
        Balanced GPDM: the dynamics term weighted by ``D/d``.
    mirror : bool
        Add every training trajectory mirrored left–right (``Δcx`` negated).
    max_iter : int
        Cap on L-BFGS iterations.
    rel_tol : float
        Stop when the objective's relative change over one round is below this.
    check_every : int
        L-BFGS iterations per round of the stopping rule.
    max_points : int
        At most this many training points (random chunks beyond it are dropped).
    chunk_length : int
        Length of the chunks long trajectories are cut into when subsampling.
    history : int
        Differences used to infer the test-time latent (the last ``history``).
    refine_iter : int
        L-BFGS iterations refining the test-time latent path (0: the best training
        window as is).
    min_history : int
        Fewest boxes for a GPDM prediction (≥ 2: one difference); below it
        :func:`predict` falls back to constant velocity.
    cv_average : int
        Differences averaged by the constant-velocity fallback.
    cv_noise : float
        Velocity noise of the fallback, in box heights per second (per frame).
    """

    latent_dim: int = 2
    obs_noise_floor: float = 1e-2
    dyn_noise_floor: float = 1e-2
    latent_scale: str = "unit"
    fix_dynamics: bool = False
    balanced: bool = False
    mirror: bool = False
    max_iter: int = 200
    rel_tol: float = 1e-6
    check_every: int = 10
    max_points: int = 1000
    chunk_length: int = 50
    history: int = 3
    refine_iter: int = 3
    min_history: int = 2
    cv_average: int = 3
    cv_noise: float = 0.2

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("latent_dim", _int_at_least("latent_dim", self.latent_dim, 1))
        for name in ("obs_noise_floor", "dyn_noise_floor"):
            set_(name, _float_in(name, getattr(self, name), 0.0, 1.0))
        for name in ("fix_dynamics", "balanced", "mirror"):
            set_(name, _bool(name, getattr(self, name)))
        if self.latent_scale not in LATENT_SCALES:
            raise ValueError(f"parameter 'latent_scale' must be one of {LATENT_SCALES}, got "
                             f"{self.latent_scale!r} (a free latent scale leaves the MAP "
                             "objective without a finite minimum)")
        set_("max_iter", _int_at_least("max_iter", self.max_iter, 0))
        set_("rel_tol", _float_in("rel_tol", self.rel_tol, 0.0, 1.0, open_low=False))
        set_("check_every", _int_at_least("check_every", self.check_every, 1))
        set_("max_points", _int_at_least("max_points", self.max_points, 3))
        set_("chunk_length", _int_at_least("chunk_length", self.chunk_length, 2))
        set_("history", _int_at_least("history", self.history, 1))
        set_("refine_iter", _int_at_least("refine_iter", self.refine_iter, 0))
        set_("min_history", _int_at_least("min_history", self.min_history, 2))
        set_("cv_average", _int_at_least("cv_average", self.cv_average, 1))
        set_("cv_noise", _float_in("cv_noise", self.cv_noise, 0.0, 1e3, open_low=False))

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-able dict."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GPDMSettings:
        """Settings from a dict; an unknown key is a ``ValueError`` naming it."""
        if not isinstance(d, dict):
            raise ValueError(f"GPDM settings must be a dict, got {type(d).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown GPDM setting(s) {unknown} (known: {sorted(known)})")
        return cls(**d)


# --------------------------------------------------------------------------- kernels


def _sqdist(a, b):
    if isinstance(a, torch.Tensor):
        d = (a * a).sum(-1)[:, None] + (b * b).sum(-1)[None, :] - 2.0 * (a @ b.T)
        return d.clamp_min(0.0)
    d = (a * a).sum(-1)[:, None] + (b * b).sum(-1)[None, :] - 2.0 * (a @ b.T)
    return np.maximum(d, 0.0)


def observation_kernel(a: np.ndarray, b: np.ndarray, beta1: float) -> np.ndarray:
    """``exp(−β₁/2 ‖a_i − b_j‖²)``, shape ``(len(a), len(b))`` (no noise term)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    return np.exp(-0.5 * float(beta1) * _sqdist(a, b))


def dynamics_kernel(a: np.ndarray, b: np.ndarray, alpha: Sequence[float]) -> np.ndarray:
    """``α₁ exp(−α₂/2 ‖a_i − b_j‖²) + α₃ a_iᵀb_j`` (no noise term; ``alpha[3]`` unused)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    a1, a2, a3 = (float(v) for v in alpha[:3])
    return a1 * np.exp(-0.5 * a2 * _sqdist(a, b)) + a3 * (a @ b.T)


def _k_obs_t(a, b, beta1):
    return torch.exp(-0.5 * beta1 * _sqdist(a, b))


def _k_dyn_t(a, b, a1, a2, a3):
    return a1 * torch.exp(-0.5 * a2 * _sqdist(a, b)) + a3 * (a @ b.T)


def _to_unit(v: float, lo: float, hi: float) -> float:
    """Raw parameter ``r`` with ``lo (hi/lo)^sigmoid(r) = v`` (``v`` clipped inside)."""
    u = math.log(v / lo) / math.log(hi / lo)
    u = min(max(u, 1e-6), 1 - 1e-6)
    return math.log(u / (1 - u))


def _from_unit(r, lo: float, hi: float):
    return lo * torch.exp(torch.sigmoid(r) * math.log(hi / lo))


# --------------------------------------------------------------------------- the model


def _segments(lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices ``(in, out, starts)`` of the dynamics pairs of concatenated sequences."""
    ends = np.cumsum(lengths)
    starts = ends - lengths
    n = int(ends[-1]) if lengths.size else 0
    last = np.zeros(n, dtype=bool)
    last[ends - 1] = True
    idx = np.arange(n)
    return idx[~last], idx[~last] + 1, starts


@dataclass(eq=False)
class GPDM:
    """A learned GPDM (arrays in the paper's notation; ``W = 1``).

    Attributes
    ----------
    X : ndarray, shape (N, d)
        Latent points of the training sequences, concatenated.
    Y : ndarray, shape (N, D)
        Standardised training observations (``(y − y_mean) / y_std``).
    lengths : ndarray of int, shape (S,)
        Length of each sequence in ``X``/``Y`` (each ≥ 2); the dynamics pairs never
        cross from one to the next.
    alpha : ndarray, shape (4,)
        ``α₁..α₄`` (``α₄`` is the dynamics noise *precision*).
    beta : ndarray, shape (2,)
        ``β₁, β₂`` (``β₂`` is the observation noise precision).
    y_mean, y_std : ndarray, shape (D,)
        Standardisation of the observations (heights per second).
    settings : GPDMSettings
    info : dict
        JSON-able notes on the training run (sources, iterations, objective trace).
    """

    X: np.ndarray
    Y: np.ndarray
    lengths: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    settings: GPDMSettings = field(default_factory=GPDMSettings)
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        def arr(name, ndim, dtype=float):
            v = np.array(getattr(self, name), dtype=dtype)
            if v.ndim != ndim:
                raise ValueError(f"field {name!r} must have {ndim} dimension(s), got shape "
                                 f"{v.shape}")
            if dtype is float and not np.all(np.isfinite(v)):
                raise ValueError(f"field {name!r} has NaN or infinite values")
            v.setflags(write=False)
            object.__setattr__(self, name, v)
            return v

        X, Y = arr("X", 2), arr("Y", 2)
        lengths = arr("lengths", 1, np.int64)
        alpha, beta = arr("alpha", 1), arr("beta", 1)
        y_mean, y_std = arr("y_mean", 1), arr("y_std", 1)
        if not isinstance(self.settings, GPDMSettings):
            raise ValueError("field 'settings' must be a GPDMSettings")
        n, d = X.shape
        if Y.shape[0] != n or n < 2:
            raise ValueError(f"fields 'X' and 'Y' must have the same number (>= 2) of rows, "
                             f"got {X.shape} and {Y.shape}")
        if d != self.settings.latent_dim:
            raise ValueError(f"field 'X' has latent dimension {d} but settings say "
                             f"{self.settings.latent_dim}")
        if lengths.size < 1 or np.any(lengths < 2) or int(lengths.sum()) != n:
            raise ValueError(f"field 'lengths' must be sequence lengths >= 2 summing to {n}")
        if alpha.shape != (4,) or np.any(alpha <= 0):
            raise ValueError(f"field 'alpha' must hold 4 positive values, got {alpha}")
        if beta.shape != (2,) or np.any(beta <= 0):
            raise ValueError(f"field 'beta' must hold 2 positive values, got {beta}")
        D = Y.shape[1]
        if y_mean.shape != (D,) or y_std.shape != (D,) or np.any(y_std <= 0):
            raise ValueError(f"fields 'y_mean' and 'y_std' must have shape ({D},) with "
                             "y_std > 0")
        self._prepare()

    # ---- precomputation -----------------------------------------------------------

    def _prepare(self) -> None:
        X = torch.tensor(self.X, dtype=_DT)
        Y = torch.tensor(self.Y, dtype=_DT)
        a1, a2, a3, a4 = (float(v) for v in self.alpha)
        b1, b2 = (float(v) for v in self.beta)
        i_in, i_out, starts = _segments(self.lengths)
        x_in, x_out = X[i_in], X[i_out]
        eye = lambda m: torch.eye(m, dtype=_DT)  # noqa: E731
        kx = _k_dyn_t(x_in, x_in, a1, a2, a3) + (1.0 / a4) * eye(len(i_in))
        ky = _k_obs_t(X, X, b1) + (1.0 / b2) * eye(X.shape[0])
        lx, ly = torch.linalg.cholesky(kx), torch.linalg.cholesky(ky)
        self._t = {"x_in": x_in, "A_x": torch.cholesky_solve(x_out, lx),
                   "Kinv_x": torch.cholesky_inverse(lx), "X": X,
                   "A_y": torch.cholesky_solve(Y, ly), "Kinv_y": torch.cholesky_inverse(ly)}
        self._in, self._out, self._starts = i_in, i_out, starts
        # fitted values at the training latents, for the test-time latent's window search
        mu_y, var_y = self.observe(self.X)
        mu_x, var_x = self.dynamics(self.X)
        self._fit = {"mu_y": mu_y, "var_y": var_y, "mu_x": mu_x, "var_x": var_x}

    @property
    def latent_dim(self) -> int:
        return int(self.X.shape[1])

    @property
    def obs_dim(self) -> int:
        return int(self.Y.shape[1])

    # ---- predictive distributions (torch inside; vectorised over points) ------------

    def _dyn_t(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        a1, a2, a3, a4 = (float(v) for v in self.alpha)
        k = _k_dyn_t(z, self._t["x_in"], a1, a2, a3)
        mu = k @ self._t["A_x"]
        kzz = a1 + a3 * (z * z).sum(-1) + 1.0 / a4
        var = kzz - ((k @ self._t["Kinv_x"]) * k).sum(-1)
        return mu, var.clamp_min(1.0 / a4)

    def _obs_t(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        b1, b2 = (float(v) for v in self.beta)
        k = _k_obs_t(z, self._t["X"], b1)
        mu = k @ self._t["A_y"]
        var = (1.0 + 1.0 / b2) - ((k @ self._t["Kinv_y"]) * k).sum(-1)
        return mu, var.clamp_min(1.0 / b2)

    def dynamics(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Latent transition ``μ_X(x)`` ``(M, d)`` and ``σ²_X(x)`` ``(M,)`` (``α₄⁻¹`` included)."""
        with torch.no_grad():
            mu, var = self._dyn_t(torch.tensor(np.atleast_2d(x), dtype=_DT))
        return mu.numpy(), var.numpy()

    def observe(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Standardised observation mean ``(M, D)`` and variance ``σ²_Y(x)`` ``(M,)``.

        The variance includes ``β₂⁻¹``; in heights per second it is ``σ²_Y(x) y_std²``
        per dimension (the paper's ``σ²_Y W⁻²``).
        """
        with torch.no_grad():
            mu, var = self._obs_t(torch.tensor(np.atleast_2d(x), dtype=_DT))
        return mu.numpy(), var.numpy()

    def mean_y(self, x: np.ndarray) -> np.ndarray:
        """``μ_Y(x) = ȳ + s ⊙ Yᵀ K_Y⁻¹ k_Y(x)`` in box heights per second, ``(M, D)``."""
        return self.y_mean + self.y_std * self.observe(x)[0]

    def standardise(self, y: np.ndarray) -> np.ndarray:
        """Observations in heights per second to the model's standardised units."""
        return (np.asarray(y, float) - self.y_mean) / self.y_std

    # ---- test-time latent ---------------------------------------------------------

    def infer_latent(self, y: np.ndarray) -> np.ndarray:
        """Current latent ``(d,)`` from the last few standardised observations ``(K, D)``.

        Maximises the joint density of a latent path ``z_1..z_K`` (observation terms,
        GP dynamics between consecutive points and the latent prior) starting from the
        best window of ``K`` consecutive training latents, refined by
        :attr:`GPDMSettings.refine_iter` L-BFGS iterations; returns ``z_K``.
        """
        y = np.atleast_2d(np.asarray(y, dtype=float))
        if y.shape[1] != self.obs_dim or y.shape[0] < 1 or not np.all(np.isfinite(y)):
            raise ValueError(f"observations must be finite with shape (K, {self.obs_dim}), "
                             f"got {y.shape}")
        k = min(y.shape[0], int(self.lengths.max()))
        y = y[-k:]
        f = self._fit
        D, d = self.obs_dim, self.latent_dim
        # observation term of every y_k at every training latent: (K, N)
        r2 = ((y[:, None, :] - f["mu_y"][None, :, :]) ** 2).sum(-1)
        nll_obs = 0.5 * r2 / f["var_y"][None] + 0.5 * D * np.log(f["var_y"])[None]
        # dynamics term of each training pair (in -> out), placed at its 'in' index
        nll_dyn = np.zeros(self.X.shape[0])
        dx = ((self.X[self._out] - f["mu_x"][self._in]) ** 2).sum(-1)
        nll_dyn[self._in] = (0.5 * dx / f["var_x"][self._in]
                             + 0.5 * d * np.log(f["var_x"][self._in]))
        pos = np.arange(self.X.shape[0]) - np.repeat(self._starts, self.lengths)
        ends = np.flatnonzero(pos >= k - 1)
        score = np.zeros(ends.shape[0])
        for j in range(k):                       # K is a handful: loop over the window
            score += nll_obs[j, ends - (k - 1) + j]
            if j < k - 1:
                score += nll_dyn[ends - (k - 1) + j]
        best = int(ends[np.argmin(score)])
        z0 = self.X[best - k + 1: best + 1]
        if self.settings.refine_iter == 0:
            return z0[-1].copy()
        with _torch_threads(1):
            return self._refine(z0, y)

    def _refine(self, z0: np.ndarray, y: np.ndarray) -> np.ndarray:
        z = torch.tensor(z0, dtype=_DT, requires_grad=True)
        yt = torch.tensor(y, dtype=_DT)
        D, d = self.obs_dim, self.latent_dim
        prior = self.settings.latent_scale == "prior"

        def objective():
            mu_y, var_y = self._obs_t(z)
            j = 0.5 * (((yt - mu_y) ** 2).sum(-1) / var_y).sum() + 0.5 * D * var_y.log().sum()
            if z.shape[0] > 1:
                mu_x, var_x = self._dyn_t(z[:-1])
                j = j + 0.5 * (((z[1:] - mu_x) ** 2).sum(-1) / var_x).sum()
                j = j + 0.5 * d * var_x.log().sum()
            if prior:
                j = j + 0.5 * (z * z).sum()
            return j

        with torch.no_grad():
            start = float(objective())
        opt = torch.optim.LBFGS([z], lr=1.0, max_iter=self.settings.refine_iter,
                                line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad()
            loss = objective()
            loss.backward()
            return loss

        opt.step(closure)
        with torch.no_grad():
            end = float(objective())
        out = z.detach().numpy()[-1]
        if not (math.isfinite(end) and end <= start and np.all(np.isfinite(out))):
            return z0[-1].copy()
        return out.copy()

    # ---- the objective (for tests and diagnostics) ----------------------------------

    def objective_terms(self) -> dict[str, float]:
        """The terms of the negative log posterior at the stored parameters.

        ``L_Y`` (without ``(ND/2) ln 2π``), ``L_X`` (weighted if balanced; with the
        starts' prior when there is no latent prior), ``prior`` and ``hyper``.
        """
        with torch.no_grad():
            terms = _objective_terms(torch.from_numpy(np.array(self.X)),
                                     *(torch.tensor(float(v), dtype=_DT) for v in self.alpha),
                                     *(torch.tensor(float(v), dtype=_DT) for v in self.beta),
                                     torch.from_numpy(np.array(self.Y)), self._in, self._out,
                                     self._starts, self.settings)
        return {k: float(v) for k, v in terms.items()}

    # ---- storage ------------------------------------------------------------------

    def save(self, path: str | Path) -> Path:
        """Write the model to ``path`` (``.npz``: arrays + a JSON header; no pickle)."""
        p = Path(path)
        header = {"format": FORMAT, "version": VERSION, "settings": self.settings.to_dict(),
                  "info": _jsonable(self.info)}
        with open(p, "wb") as f:
            np.savez(f, header=np.array(json.dumps(header)),
                     **{name: np.asarray(getattr(self, name)) for name in _ARRAYS})
        return p


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if obj is None or isinstance(obj, str):
        return obj
    return str(obj)


def load_gpdm(path: str | Path) -> GPDM:
    """Read a model written by :meth:`GPDM.save`, validating every field.

    Raises
    ------
    InputError
        (a ``ValueError``) naming the file and the problem: missing file, not an
        ``.npz``, a missing field, a field with NaN/inf, a bad shape, an unknown format
        or version, or invalid settings.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"GPDM model file not found: {p}")
    try:
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(f"{p}: not a readable GPDM .npz file ({one_line(e)})") from None
    for name in ("header",) + _ARRAYS:
        if name not in data:
            raise InputError(f"{p}: missing field {name!r}")
    try:
        header = json.loads(str(data["header"][()]))
        if not isinstance(header, dict):
            raise ValueError("not a JSON object")
    except (ValueError, TypeError, IndexError) as e:
        raise InputError(f"{p}: field 'header' is not valid JSON ({one_line(e)})") from None
    except RecursionError:
        raise InputError(f"{p}: field 'header' is nested too deeply") from None
    for key in ("format", "version", "settings"):
        if key not in header:
            raise InputError(f"{p}: missing header field {key!r}")
    if header["format"] != FORMAT:
        raise InputError(f"{p}: header format is {header['format']!r}, expected {FORMAT!r}")
    if header["version"] != VERSION:
        raise InputError(f"{p}: unsupported GPDM file version {header['version']!r} "
                         f"(this toolkit reads version {VERSION})")
    arrays = {}
    for name in _ARRAYS:
        v = data[name]
        if v.dtype.kind not in "fiu":
            raise InputError(f"{p}: field {name!r} must be numeric, got dtype {v.dtype}")
        if v.dtype.kind == "f" and not np.all(np.isfinite(v)):
            raise InputError(f"{p}: field {name!r} has NaN or infinite values")
        arrays[name] = v
    try:
        settings = GPDMSettings.from_dict(header["settings"])
    except (ValueError, TypeError) as e:
        raise InputError(f"{p}: header settings: {one_line(e)}") from None
    info = header.get("info", {})
    try:
        return GPDM(settings=settings, info=info if isinstance(info, dict) else {}, **arrays)
    except (ValueError, torch.linalg.LinAlgError) as e:
        raise InputError(f"{p}: {one_line(e)}") from None


def _objective_terms(X, a1, a2, a3, nx_prec, b1, ny_prec, Y, i_in, i_out, starts, s):
    """Terms of the negative log posterior (torch; ``nx_prec`` = α₄, ``ny_prec`` = β₂)."""
    n, D = Y.shape
    d = X.shape[1]
    eye = lambda m: torch.eye(m, dtype=_DT)  # noqa: E731
    ky = _k_obs_t(X, X, b1) + eye(n) / ny_prec
    ly = torch.linalg.cholesky(ky)
    l_y = D * torch.log(torch.diagonal(ly)).sum() + 0.5 * (Y * torch.cholesky_solve(Y, ly)).sum()
    x_in, x_out = X[i_in], X[i_out]
    kx = _k_dyn_t(x_in, x_in, a1, a2, a3) + eye(len(i_in)) / nx_prec
    lx = torch.linalg.cholesky(kx)
    l_x = (d * torch.log(torch.diagonal(lx)).sum()
           + 0.5 * (x_out * torch.cholesky_solve(x_out, lx)).sum())
    with_prior = s.latent_scale == "prior"
    if not with_prior:
        l_x = l_x + 0.5 * (X[starts] ** 2).sum()
    if s.balanced:
        l_x = l_x * (D / d)
    prior = 0.5 * (X * X).sum() if with_prior else torch.zeros((), dtype=_DT)
    hyper = (torch.log(a1) + torch.log(a2) + torch.log(a3) + torch.log(nx_prec)
             + torch.log(b1) + torch.log(ny_prec))
    return {"L_Y": l_y, "L_X": l_x, "prior": prior, "hyper": hyper}


@contextlib.contextmanager
def _torch_threads(n: int):
    """Run with ``n`` torch threads, restoring the caller's count afterwards.

    The matrices here are small (≤ ``max_points``); extra intra-op threads only add
    contention (a 20× slow-down was measured on a busy two-core machine).
    """
    old = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)
