r"""Factors for many targets (PHD filters) and for adaptive measurement noise (VB).

* :class:`IntensityPrior` — the initial intensity of a ``set`` variable (empty by
  default: targets are born from measurements).
* :class:`PHDLikelihood` — point measurements ``z = H x + v`` of a random finite set
  (eq. (2) of [#feng2015] misprints it as ``z_t = H z_{t−1} + v``) with detection
  probability ``p_D``, Poisson clutter ``κ = λ_c / A`` and measurement-driven births
  ``ν_b = λ_b / A`` (the particle PHD filter of [#vo2005], births as in [#ristic2012]).
  Its ``log_g`` evaluates the ``(N, |Z|)`` log-likelihood matrix either with a fixed
  diagonal ``R`` or with the variational ``E_q[log N(z; Hx, R)]`` of an inverse-Gamma
  noise belief (§II-B of [#feng2015]). Other likelihood factors declared on the same set
  variable are *appearance* terms: their per-particle log-scores multiply the detection
  terms (as the DBN of §II-C of [#feng2015] does), so a learned appearance model slots in
  as one more factor.
* :class:`InverseGammaPrior`, :class:`NoiseForgetting`, :class:`VBNoise` — the
  ``noise`` variable's prior, its forgetting transition (``α̂ = ρα, β̂ = ρβ``, floored)
  and the conjugate factor that ties it to the likelihood it parameterises.

References
----------
.. [#vo2005] B.-N. Vo, S. Singh and A. Doucet, "Sequential Monte Carlo methods for multitarget
   filtering with random finite sets", IEEE Trans. Aerospace and Electronic Systems 41(4),
   1224–1245, 2005. doi:10.1109/TAES.2005.1561884
.. [#ristic2012] B. Ristic, D. Clark, B.-N. Vo and B.-T. Vo, "Adaptive target birth intensity
   for PHD and CPHD filters", IEEE Trans. Aerospace and Electronic Systems 48(2),
   1656–1668, 2012. doi:10.1109/TAES.2012.6178085
.. [#feng2015] P. Feng, W. Wang, S. M. Naqvi and J. A. Chambers, "Variational Bayesian PHD
   filter with deep learning network updating for multiple human tracking", Proc. Sensor
   Signal Processing for Defence (SSPD), Edinburgh, 2015 (venue inferred; DOI not confirmed).
.. [#sarkka2009] S. Särkkä and A. Nummenmaa, "Recursive noise adaptive Kalman filtering by
   variational Bayesian approximations", IEEE Trans. Automatic Control 54(3), 596–600, 2009.
   doi:10.1109/TAC.2008.2008348
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param, scratch
from pgm.core.variable import Variable
from pgm.factors.gaussian import _as_cov, _sqrt_psd
from pgm.factors.kinds import ConjugateFactor, LikelihoodFactor, PriorFactor, TransitionFactor
from pgm.factors.scores import ScoreSettings

__all__ = ["IntensityPrior", "PHDLikelihood", "TrackSettings", "ScoreSettings",
           "InverseGammaPrior",
           "NoiseForgetting", "VBNoise", "constant_velocity"]

LOG_G_FLOOR = -300.0  # numerics: below -708 numpy's exp goes subnormal and slow


def constant_velocity(dt: float, q: float, layout: str = "pv",
                      q_log_h: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``F, Q`` of a 2-D nearly-constant-velocity model (white-noise acceleration, density q).

    ``layout="pv"``: state ``[px, vx, py, vy]`` (the bench scenario, Stone Soup);
    ``layout="pp"``: state ``[px, py, vx, vy]``. With ``q_log_h`` (``"pv"`` only) a third
    axis, the log-height and its rate, with its own density: ``[px, vx, py, vy, log_h,
    v_log_h]``.
    """
    F1 = np.array([[1.0, dt], [0.0, 1.0]])
    G = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    F = np.kron(np.eye(2), F1)
    Q = np.kron(np.eye(2), q * G)
    if q_log_h is not None:
        if layout != "pv":
            raise ValueError("a log-height axis needs layout 'pv'")
        F = np.kron(np.eye(3), F1)
        Q = np.zeros((6, 6))
        Q[:4, :4] = np.kron(np.eye(2), q * G)
        Q[4:, 4:] = q_log_h * G
        return F, Q
    if layout == "pv":
        return F, Q
    if layout == "pp":
        perm = [0, 2, 1, 3]
        return F[np.ix_(perm, perm)], Q[np.ix_(perm, perm)]
    raise ValueError(f"layout must be 'pv' or 'pp', got {layout!r}")


class IntensityPrior(PriorFactor):
    """Initial intensity: ``mass`` targets spread as ``N(mean, cov)`` (default: none)."""

    def __init__(self, variable: str, *, mean, cov=0.0, mass: float = 0.0,
                 name: str | None = None):
        super().__init__(variable, name=name)
        self.mean_ = np.atleast_1d(np.asarray(mean, dtype=float))
        check_finite_param(f"{self.name}.mean", self.mean_)
        self.cov = _as_cov(cov, self.mean_.size, f"{self.name}.cov")
        self._sqrt = _sqrt_psd(self.cov, f"factor {self.name!r}: cov")
        self.mass = float(check_finite_param(f"{self.name}.mass", mass, nonneg=True))

    def params(self) -> dict[str, Any]:
        return {"mean": self.mean_, "cov": self.cov, "mass": self.mass}

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.mean_.size, "the prior mean")

    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        return self.mean_ + rng.standard_normal((num, self.mean_.size)) @ self._sqrt.T

    def mean(self) -> np.ndarray:
        return self.mean_.copy()


@dataclass(frozen=True)
class TrackSettings:
    """The track layer on top of PHD extraction (:mod:`pgm.inference.tracks`).

    Attributes
    ----------
    gate : float
        Assignment gate in measurement σ.
    confirm_hits : int
        Hits before a track is confirmed (and given an identity).
    max_coast : int
        Frames a confirmed track is predicted and reported without a hit.
    max_lost : int, optional
        Frames a confirmed track is kept (unreported) for re-identification after
        coasting (None: no lost stage).
    """

    gate: float = 5.0
    confirm_hits: int = 3
    max_coast: int = 2
    max_lost: int | None = None

    def __post_init__(self) -> None:
        check_finite_param("tracks.gate", self.gate, positive=True)
        for name in ("confirm_hits", "max_coast", "max_lost"):
            v = getattr(self, name)
            if v is None and name == "max_lost":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"tracks.{name} must be a non-negative integer, got {v!r}")

    @classmethod
    def coerce(cls, value: TrackSettings | dict[str, Any] | None, what: str) -> TrackSettings:
        """``value`` as settings (a dict from a saved graph is checked key by key)."""
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if not isinstance(value, dict):
            raise ValueError(f"{what} must be TrackSettings or a dict, got {value!r}")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(value) - names)
        if unknown:
            raise ValueError(f"{what}: unknown setting(s) {unknown} (known: {sorted(names)})")
        return cls(**value)


class PHDLikelihood(LikelihoodFactor):
    r"""Point measurements of a random finite set (particle PHD corrector of [#vo2005]).

    Parameters
    ----------
    variable : str
        The ``set`` variable.
    H : array_like (k, d)
        Measurement matrix; each row selects one state component (births invert it).
    R : array_like (k,) or (k, k) diagonal
        Measurement-noise variances (the fixed ``R`` of the plain PHD filter; with a
        :class:`VBNoise` factor the noise belief replaces it).
    p_detect : float
        ``p_D``.
    clutter_rate : float
        ``λ_c``, expected clutter measurements per frame; ``κ = λ_c / area``.
    area : float
        Measurement-space area ``A`` (image width × height in px², or region in m²).
    birth_rate : float
        ``λ_b``, expected targets born per frame; ``ν_b = λ_b / area``.
    n_birth : int
        Newborn particles per measurement.
    birth_velocity_std : float
        σ of the newborn velocity components (about a typical target speed).
    velocity_indices : sequence of int
        State components drawn from ``N(0, birth_velocity_std²)`` at birth.
    appearance_temper : float
        ``γ``: exponent of the appearance terms (other likelihood factors on the set).
    min_particles : int
        Floor of the intensity's resampling budget
        ``max(min_particles, round(num_particles · mass))``.
    regularise : bool
        Regularised resampling (:mod:`pgm.inference.phd_regularise`): each resampled
        particle moved by a kernel of the posterior of the measurement that explains it
        (shrunk so the target's mean and covariance are kept), against sample
        impoverishment when the transition's noise is small. Off by default.
    merge_gate : float
        Extraction: estimates closer than this many σ are one target.
    tracks : TrackSettings or dict
        The track layer on top of extraction (identities, confirmation, coasting).
    scale_index : int, optional
        **Scale-aware noise**: the state component holding the target's log-height
        ``log h``. The measured components flagged in ``scaled`` then have noise
        variance ``R_i h²`` — ``R_i`` is *relative*, in units of the target's own height
        — and the newborn velocities have std ``birth_velocity_std · h``; so one setting
        serves a person near the camera and one far away, and a VB noise belief learns
        the relative variance. Detections are then measured as
        ``(foot x, foot y, log h)`` when ``H`` has three rows.
    scaled : sequence of bool, optional
        Which measured components scale with the height (default: all but the one that
        measures ``log h``).
    log_h_range : float
        With a ``log h`` measurement: the extent of the log-heights where clutter and
        births can appear (clutter density ``κ = λ_c / (A · log_h_range)``).
    scores : ScoreSettings, dict or str, optional
        How detection scores enter (:mod:`pgm.factors.scores`): ``"off"`` (default:
        score-blind) or ``"mixture"`` — a per-detection clutter intensity
        ``κ(s) = κ (f_C(s)/f_T(s))^γ`` from a two-class mixture fitted online to the
        video's own scores, and no births from low-score detections (they may only
        update existing targets).
    """

    def __init__(self, variable: str, *, H, R, p_detect: float = 0.9,
                 clutter_rate: float = 1.0, area: float = 1.0, birth_rate: float = 0.1,
                 n_birth: int = 100, birth_velocity_std: float = 1.0,
                 velocity_indices=(), appearance_temper: float = 1.0,
                 min_particles: int = 200, regularise: bool = False,
                 merge_gate: float = 2.0,
                 tracks: TrackSettings | dict[str, Any] | None = None,
                 scale_index: int | None = None, scaled=None, log_h_range: float = 1.0,
                 scores: ScoreSettings | dict[str, Any] | str | None = None,
                 name: str | None = None):
        super().__init__(variable, name=name)
        self.H = np.atleast_2d(np.asarray(H, dtype=float))
        check_finite_param(f"{self.name}.H", self.H)
        R = np.asarray(R, dtype=float)
        self.R = np.diag(R).copy() if R.ndim == 2 else np.atleast_1d(R).copy()
        if R.ndim == 2 and np.count_nonzero(R - np.diag(np.diag(R))):
            raise ValueError(f"factor {self.name!r}: R must be diagonal")
        check_finite_param(f"{self.name}.R", self.R, positive=True)
        if self.R.shape != (self.H.shape[0],):
            raise ValueError(f"factor {self.name!r}: R has {self.R.size} entries for "
                             f"{self.H.shape[0]} measurement components")
        self.p_detect = float(check_finite_param(f"{self.name}.p_detect", p_detect))
        if not 0.0 < self.p_detect <= 1.0:
            raise ValueError(f"factor {self.name!r}: p_detect must be in (0, 1]")
        self.clutter_rate = float(check_finite_param(f"{self.name}.clutter_rate", clutter_rate,
                                                     nonneg=True))
        self.area = float(check_finite_param(f"{self.name}.area", area, positive=True))
        self.birth_rate = float(check_finite_param(f"{self.name}.birth_rate", birth_rate,
                                                   nonneg=True))
        self.n_birth = int(n_birth)
        if self.n_birth < 1:
            raise ValueError(f"factor {self.name!r}: n_birth must be positive")
        self.birth_velocity_std = float(check_finite_param(
            f"{self.name}.birth_velocity_std", birth_velocity_std, nonneg=True))
        self.velocity_indices = tuple(int(i) for i in velocity_indices)
        self.appearance_temper = float(check_finite_param(
            f"{self.name}.appearance_temper", appearance_temper, nonneg=True))
        self.min_particles = int(min_particles)
        if isinstance(min_particles, bool) or self.min_particles != min_particles \
                or self.min_particles < 0:
            raise ValueError(f"factor {self.name!r}: min_particles must be a non-negative "
                             f"integer, got {min_particles!r}")
        if not isinstance(regularise, (bool, np.bool_)):
            raise ValueError(f"factor {self.name!r}: regularise must be True or False, got "
                             f"{regularise!r}")
        self.regularise = bool(regularise)
        self.merge_gate = float(check_finite_param(f"{self.name}.merge_gate", merge_gate,
                                                   positive=True))
        self.tracks = TrackSettings.coerce(tracks, f"factor {self.name!r}: tracks")
        self.scores = ScoreSettings.coerce(scores, f"factor {self.name!r}: scores")
        # rows of H that pick one component with coefficient 1 -> births invert them
        self._pos_index = [int(np.argmax(np.abs(row))) for row in self.H]
        self.scale_index = None if scale_index is None else int(scale_index)
        k = self.H.shape[0]
        if self.scale_index is None:
            self.scaled = np.zeros(k, dtype=bool)
        elif scaled is None:
            self.scaled = np.array([i != self.scale_index for i in self._pos_index])
        else:
            self.scaled = np.asarray(scaled, dtype=bool).reshape(-1)
            if self.scaled.shape != (k,):
                raise ValueError(f"factor {self.name!r}: scaled needs {k} entries")
        self.log_h_range = float(check_finite_param(f"{self.name}.log_h_range", log_h_range,
                                                    positive=True))
        #: measurement row that measures log h (None: detections give foot points only)
        self.log_h_row = None
        if self.scale_index is not None:
            if self.scale_index not in self._pos_index:
                raise ValueError(f"factor {self.name!r}: scale-aware noise needs a measured "
                                 f"log-height (a row of H picking state {self.scale_index})")
            self.log_h_row = self._pos_index.index(self.scale_index)

    def params(self) -> dict[str, Any]:
        p = {"H": self.H, "R": self.R, "p_detect": self.p_detect,
                "clutter_rate": self.clutter_rate, "area": self.area,
                "birth_rate": self.birth_rate, "n_birth": self.n_birth,
                "birth_velocity_std": self.birth_velocity_std,
                "velocity_indices": list(self.velocity_indices),
                "appearance_temper": self.appearance_temper,
                "min_particles": self.min_particles, "merge_gate": self.merge_gate,
                "tracks": dataclasses.asdict(self.tracks)}
        if self.regularise:  # factors without it save as before
            p["regularise"] = True
        if self.scores.enabled:  # score-blind factors save as before
            p["scores"] = self.scores.to_dict()
        if self.scale_index is not None:
            p.update(scale_index=self.scale_index, scaled=self.scaled.tolist(),
                     log_h_range=self.log_h_range)
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        v = variables[self.variables[0]]
        if v.role != "set":
            raise ValueError(f"factor {self.name!r}: variable {v.name!r} must have role 'set'")
        self._check_dim(variables, v.name, self.H.shape[1], "H's column count")
        if any(i >= v.dim for i in self.velocity_indices):
            raise ValueError(f"factor {self.name!r}: velocity_indices out of range")
        if self.scale_index is not None and self.scale_index >= v.dim:
            raise ValueError(f"factor {self.name!r}: scale_index out of range")

    # -- pieces used by the PHD / VB-PHD rules --------------------------------------------
    @property
    def _volume(self) -> float:
        """Measurement-space volume: the area, times the log-height extent if measured."""
        return self.area * (self.log_h_range if self.log_h_row is not None else 1.0)

    @property
    def kappa(self) -> float:
        """Clutter intensity ``κ = λ_c / V`` (``V``: the area, × the log-height extent)."""
        return self.clutter_rate / self._volume

    @property
    def nu_birth(self) -> float:
        """Birth measurement density ``ν_b = λ_b / V``."""
        return self.birth_rate / self._volume

    def log_scale(self, x: np.ndarray) -> np.ndarray | None:
        """``(N,)`` log-heights of the particles (None without scale-aware noise)."""
        return None if self.scale_index is None else x[:, self.scale_index]

    def measurements(self, ctx: FrameContext) -> np.ndarray:
        """This frame's measurements ``(M, k)``: ``ctx.measurements``, or the foot points
        of ``ctx.detections`` when only detections are given."""
        z = ctx.measurements
        if z is None and getattr(ctx, "detections", None) is not None:
            z = ctx.detections.foot_points
            if self.log_h_row is not None:  # (foot x, foot y) + log h, in H's row order
                boxes = ctx.detections.boxes
                cols = [z[:, 0], z[:, 1]]
                cols.insert(self.log_h_row, np.log(np.maximum(boxes[:, 3], 1e-6)))
                z = np.stack(cols, axis=1)
        if z is None:
            return np.zeros((0, self.H.shape[0]))
        z = np.asarray(z, dtype=float).reshape(-1, self.H.shape[0])
        return z

    def detection_scores(self, ctx: FrameContext) -> np.ndarray | None:
        """This frame's detection scores ``(M,)`` (None when the measurements carry none:
        given directly as ``ctx.measurements``, or no detections)."""
        dets = getattr(ctx, "detections", None)
        if ctx.measurements is not None or dets is None:
            return None
        return np.asarray(dets.scores, dtype=float).reshape(-1)

    def sq_dist(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``(k, M, N)`` squared residuals ``(z_i − (H x)_i)²`` per measured component,
        measurement-major (each ``[i]`` C-contiguous; ``[i].T`` is the ``(N, M)`` view).
        The VB fixed point computes them once per frame and reuses them in every
        iteration's :meth:`log_g` and noise statistics."""
        pred = x @ self.H.T  # (N, k)
        out = np.empty((z.shape[1], z.shape[0], x.shape[0]))
        inv_h2 = None if self.scale_index is None else np.exp(-2.0 * x[:, self.scale_index])
        for i in range(z.shape[1]):  # k components, vectorised over measurements x particles
            np.subtract(z[:, i, None], pred[None, :, i], out=out[i])
            np.square(out[i], out=out[i])
            if inv_h2 is not None and self.scaled[i]:
                out[i] *= inv_h2[None, :]  # residual in units of the particle's height
        return out

    def log_g(self, x: np.ndarray, z: np.ndarray, precision: np.ndarray | None = None,
              log_variance: np.ndarray | None = None, sq: np.ndarray | None = None
              ) -> np.ndarray:
        r"""``(N, M)`` matrix of ``log g(z | x)``, floored at ``LOG_G_FLOOR``.

        With ``precision = E[1/σ²]`` and ``log_variance = E[log σ²]`` of a noise belief
        this is the variational ``log g̃`` of the VB-PHD update (constant included); by default
        the plug-in Gaussian with the factor's ``R``. Both may be ``(k,)`` (one noise
        shared by all particles) or ``(N, k)`` (per-particle, e.g. per-track noise).
        ``sq``: the :meth:`sq_dist` of ``x`` and ``z`` when already computed (the result
        is the same, bit for bit).
        """
        prec = 1.0 / self.R if precision is None else np.asarray(precision, dtype=float)
        logv = np.log(self.R) if log_variance is None else np.asarray(log_variance, dtype=float)
        const = -0.5 * z.shape[1] * np.log(2 * np.pi) - 0.5 * np.sum(logv, axis=-1)
        const = const[:, None] if np.ndim(const) else float(const)
        if self.scale_index is not None:  # -log h per scaled component: the density in px
            const = const - self.scaled.sum() * x[:, self.scale_index][:, None]
        prec = prec.T[:, :, None] if prec.ndim == 2 else prec  # (k, N, 1) per particle
        # stored (M, N), returned as its (N, M) transpose: reductions over particles run
        # along contiguous rows (about 2x faster than (N, M) with few measurements)
        out = np.empty((z.shape[0], x.shape[0])).T
        tmp = scratch(self, "_log_g_tmp", out.T.shape).T  # reused, see pgm.core.numerics.scratch
        pred = x @ self.H.T if sq is None else None  # (N, k)
        inv_h2 = (np.exp(-2.0 * x[:, self.scale_index])[:, None]
                  if sq is None and self.scale_index is not None else None)
        for i in range(z.shape[1]):  # k is 2: a loop over components, not particles
            buf = out if i == 0 else tmp
            if sq is None:
                np.subtract(z[None, :, i], pred[:, i, None], out=buf)
                np.square(buf, out=buf)
                buf *= -0.5 * prec[i]
                if inv_h2 is not None and self.scaled[i]:
                    buf *= inv_h2
            else:
                np.multiply(sq[i].T, -0.5 * prec[i], out=buf)
            if i:
                out += buf
        out += const
        np.maximum(out, LOG_G_FLOOR, out=out)
        return out

    def births(self, rng: np.random.Generator, z: np.ndarray, r_hat: np.ndarray,
               d: int) -> np.ndarray:
        """``n_birth`` newborn particles per measurement, shape ``(M * n_birth, d)``:
        measured components at ``z + N(0, R̂)``, velocities ``N(0, σ_v²)``, others 0."""
        m = z.shape[0]
        x = np.zeros((m * self.n_birth, d))
        zz = np.repeat(z, self.n_birth, axis=0)
        noise = rng.standard_normal(zz.shape) * np.sqrt(r_hat)
        h = None
        if self.scale_index is not None:  # the measured height sets the newborns' scale
            h = np.exp(zz[:, self.log_h_row])
            noise[:, self.scaled] *= h[:, None]
        for row, idx in enumerate(self._pos_index):
            x[:, idx] = (zz[:, row] + noise[:, row]) / self.H[row, idx]
        for idx in self.velocity_indices:
            x[:, idx] = self.birth_velocity_std * rng.standard_normal(x.shape[0])
            if h is not None:
                x[:, idx] *= h
        return x

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        """Per-particle PHD update factor ``log[(1 − p_D) + Σ_z p_D g(z|x) / L(z)]``
        for a single-particle-set view; the set rule uses :meth:`log_g` directly."""
        raise ValueError(f"factor {self.name!r} updates a set variable; run it through the "
                         f"engine (rule ('likelihood', Intensity))")


class InverseGammaPrior(PriorFactor):
    """``σ²_i ~ IG(α_0, β_0)`` with ``β_0 = α_0 σ_0²`` (so that ``R̂ = β/α = σ_0²``)."""

    def __init__(self, variable: str, *, sigma, alpha: float = 10.0, name: str | None = None):
        super().__init__(variable, name=name)
        self.sigma = np.atleast_1d(np.asarray(sigma, dtype=float))
        check_finite_param(f"{self.name}.sigma", self.sigma, positive=True)
        self.alpha = float(check_finite_param(f"{self.name}.alpha", alpha, positive=True))

    def params(self) -> dict[str, Any]:
        return {"sigma": self.sigma, "alpha": self.alpha}

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.sigma.size, "sigma")

    def belief(self):
        """The initial :class:`~pgm.core.expfam.InverseGamma` belief."""
        from pgm.core.expfam import InverseGamma

        return InverseGamma.from_sigma(self.sigma, self.alpha)

    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        b = self.belief()
        return b.beta / rng.gamma(b.alpha, 1.0, size=(num, b.dim))

    def mean(self) -> np.ndarray:
        return self.sigma**2


class NoiseForgetting(TransitionFactor):
    """Forgetting of a noise belief between frames: ``α̂ = ρα, β̂ = ρβ`` (eq. (18) of
    [#feng2015], after [#sarkka2009]),
    with both multiplied by ``max(1, α_min/α̂)`` so that ``α̂ ≥ α_min``."""

    order = 1

    def __init__(self, variable: str, *, rho: float = 0.8, alpha_min: float = 2.0,
                 name: str | None = None):
        super().__init__(variable, name=name)
        self.rho = float(check_finite_param(f"{self.name}.rho", rho))
        if not 0.0 < self.rho <= 1.0:
            raise ValueError(f"factor {self.name!r}: rho must be in (0, 1], got {rho}")
        self.alpha_min = float(check_finite_param(f"{self.name}.alpha_min", alpha_min,
                                                  nonneg=True))

    def params(self) -> dict[str, Any]:
        return {"rho": self.rho, "alpha_min": self.alpha_min}

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        return np.asarray(past[0], dtype=float)


def vb_likelihood_refusal(factor, graph) -> ValueError:
    """The error of a :class:`VBNoise` factor that does not find exactly one likelihood to
    parameterise: what it asked for and what its target has."""
    target = factor.variables[1]
    names = [f.name for f in graph.factors_of(target, "likelihood")]
    asked = f" named {factor.likelihood!r}" if factor.likelihood is not None else ""
    return ValueError(f"factor {factor.name!r}: needs one likelihood on {target!r}{asked}; "
                      f"{target!r} has {names or 'none'}")


class VBNoise(ConjugateFactor):
    """Mean-field VB between a noise belief and the likelihood it parameterises.

    Parameters
    ----------
    noise, target : str
        The ``noise`` variable and the state/set variable it acts on.
    likelihood : str, optional
        Name of the parameterised likelihood factor (default: the target's likelihoods).
    tol : float
        Stop when the relative change of ``R̂ = β/α`` is below ``tol``.
    max_iter : int
        Cap on fixed-point passes (``n_max``).
    strict_counts : bool
        Count only measurements with ``W_z ≥ 0.5`` in the noise statistics (halves the
        clutter bias at small σ but breaks the ELBO guarantee). Off by default.
    per_track : bool
        One noise belief per track instead of one shared by all targets: particles carry
        a lineage label (one per birth), each label has its own inverse-Gamma belief,
        and each label's statistics are summed over its own particles (Algorithm 1 of
        [#feng2015] carries ``(α, β)`` per particle; this is its per-track form).
    tie : sequence of int, optional
        Tied measurement components: one group label per component, and components with
        the same label share one variance (e.g. ``(0, 0)``: one isotropic variance for a
        foot point's x and y; ``(0, 0, 1)`` with a log-height). A tied group's belief is
        one inverse-Gamma whose statistics are summed over its components, so it learns
        from ``|group|`` times as many squared residuals; its prior is the average of its
        components' priors. Default None: every component has its own variance. The
        VB-PHD (intensity) rule only.
    """

    def __init__(self, noise: str, target: str, *, likelihood: str | None = None,
                 tol: float = 1e-3, max_iter: int = 10, strict_counts: bool = False,
                 per_track: bool = False, tie=None, name: str | None = None):
        super().__init__(noise, target, likelihood=likelihood, name=name)
        self.per_track = bool(per_track)
        self.tie = None
        if tie is not None:
            arr = np.asarray(tie)
            if arr.ndim != 1 or arr.size == 0 or not np.issubdtype(arr.dtype, np.integer):
                raise ValueError(f"factor {self.name!r}: tie must be a sequence of integer "
                                 f"group labels, got {tie!r}")
            self.tie = tuple(int(v) for v in arr)
        self.tol = float(check_finite_param(f"{self.name}.tol", tol, nonneg=True))
        self.max_iter = int(max_iter)
        if self.max_iter < 1:
            raise ValueError(f"factor {self.name!r}: max_iter must be positive")
        self.strict_counts = bool(strict_counts)

    def params(self) -> dict[str, Any]:
        p = super().params()
        p.update(tol=self.tol, max_iter=self.max_iter)
        if self.strict_counts:
            p["strict_counts"] = True
        if self.per_track:
            p["per_track"] = True
        if self.tie is not None:  # untied factors save as before
            p["tie"] = list(self.tie)
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        if self.tie is not None:
            self._check_dim(variables, self.variables[0], len(self.tie), "tie")
