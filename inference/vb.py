r"""Mean-field variational Bayes as rules of the engine (the VB-PHD filter of [#feng2015]).

Noise variables (role ``noise``) hold an :class:`~pgm.core.expfam.InverseGamma` belief:
prior from :class:`~pgm.factors.multitarget.InverseGammaPrior`, forgetting prediction
(``α̂ = ρα, β̂ = ρβ``, floored) from :class:`~pgm.factors.multitarget.NoiseForgetting`. A
conjugate factor (:class:`~pgm.factors.multitarget.VBNoise`) runs the fixed point between the
target's belief and the noise belief each frame, dispatched on the target's belief:

* ``Gaussian`` — the VB adaptive Kalman filter (Särkkä & Nummenmaa [#sarkka2009]), the exact
  closed form: ``α = α̂ + ½``; repeat ``R̂ = diag(β/α)``, Kalman update with ``R̂``,
  ``β = β̂ + ½ (z − H m)² + ½ diag(H P Hᵀ)``;
* ``Intensity`` — the VB-PHD filter (§II-B of [#feng2015]): the PHD corrector with
  ``log g̃(z|x) = −(d/2) ln 2π − ½ Σ_i (ln β_i − ψ(α_i)) − ½ Σ_i (α_i/β_i)(z − Hx)_i²``,
  then ``α = α̂ + ½ Σ_z W_z``, ``β = β̂ + ½ Σ_z Σ_j ω_jz (z − Hx_j)²`` over persistent
  particles; the first pass uses ``α = α̂ + ½ min(|Z|, p_D Σ_j w_j)``, ``β = β̂``;
* ``Particles`` — any likelihood with the conjugate contract ``noise_residuals(x, frame)``
  (residuals with independent Gaussian noise of the noise variances): the predicted
  particles reweighted by ``exp E[log p(y | x, σ²)]``, then ``α = α̂ + ½``,
  ``β = β̂ + ½ Σ_i w_i r_i²``, repeated.

With ``VBNoise(tie=...)`` the tied components share one variance: their statistics are
summed (``α`` gains ``|group|/2`` per unit of association weight) and the ELBO counts each
group's KL once.

All stop when the relative change of ``R̂ = β/α`` is below ``tol`` or after
``max_iter`` passes, and record the ELBO after every state update
(``record.info[factor]["elbo"]``); it never decreases.

This module also holds the exact Gaussian rules (Kalman predict/update) used when a
``state`` variable is given a ``Gaussian`` belief.

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
from typing import Any

import numpy as np

from pgm.core.batched import BatchedInverseGamma
from pgm.core.beliefs import Intensity, Particles
from pgm.core.expfam import Gaussian, InverseGamma
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.factors.multitarget import (
    InverseGammaPrior,
    NoiseForgetting,
    PHDLikelihood,
    VBNoise,
    vb_likelihood_refusal,
)

from .context import RuleContext
from .info import VBInfo
from .kalman import kalman_update, vb_akf_batch
from .phd import PHDState, _finish, _update, phd_factor_of
from .rules import RuleTable

__all__ = ["vb_akf_update", "gaussian_elbo_terms"]

#: the rules of this family (:func:`pgm.inference.default_rules` gathers every family's)
RULES = RuleTable()


# -- noise beliefs -------------------------------------------------------------------------
@RULES.register(InverseGammaPrior, InverseGamma)
def _prior_noise(ctx: RuleContext, factor, frame) -> None:
    ctx.beliefs[factor.variables[0]] = factor.belief()


@RULES.register(NoiseForgetting, InverseGamma)
def _forget_noise(ctx: RuleContext, factor, frame) -> None:
    var = factor.variables[0]
    ctx.beliefs[var] = ctx.beliefs[var].forget(factor.rho, factor.alpha_min)


@RULES.register("estimate", InverseGamma)
def _estimate_noise(ctx: RuleContext, variable: str, frame) -> np.ndarray:
    return ctx.beliefs[variable].r_hat()


# -- a plate's noise beliefs, all replicas at once ------------------------------------------
@RULES.register(InverseGammaPrior, BatchedInverseGamma)
def _prior_noise_batched(ctx: RuleContext, factor, frame) -> None:
    """Each replica's prior belief (from its own prior factor, re-centred at its birth),
    stacked."""
    ctx.beliefs[factor.variables[0]] = BatchedInverseGamma.stack(
        [g.factors[factor.name].belief() for g in ctx.replicas.graphs])


@RULES.register(NoiseForgetting, BatchedInverseGamma)
def _forget_noise_batched(ctx: RuleContext, factor, frame) -> None:
    """The forgetting prediction of every replica's noise belief."""
    var = factor.variables[0]
    ctx.beliefs[var] = ctx.beliefs[var].forget(factor.rho, factor.alpha_min)


@RULES.register("estimate", BatchedInverseGamma)
def _estimate_noise_batched(ctx: RuleContext, variable: str, frame) -> np.ndarray:
    """``β/α`` per replica, ``(K, d)``."""
    return ctx.beliefs[variable].r_hat()



# -- exact Gaussian rules (Kalman) ------------------------------------------------------------
@RULES.register(GaussianPrior, Gaussian)
def _prior_gaussian(ctx: RuleContext, factor, frame) -> None:
    ctx.beliefs[factor.variables[0]] = Gaussian(factor.mean(), factor.cov)


@RULES.register(LinearGaussianTransition, Gaussian)
def _predict_gaussian(ctx: RuleContext, factor, frame) -> None:
    var = factor.variables[0]
    g: Gaussian = ctx.beliefs[var]
    ctx.beliefs[var] = Gaussian(factor.F @ g.m, factor.F @ g.P @ factor.F.T + factor.Q)


def _measurement(factor, frame):
    if hasattr(factor, "measurement"):  # checked: its length and finiteness, named
        return factor.measurement(frame)
    z = frame.measurements
    if isinstance(z, dict):
        z = z.get(factor.key if getattr(factor, "key", None) else factor.variables[0])
    return None if z is None else np.asarray(z, dtype=float).reshape(-1)


def _kalman_update(g: Gaussian, H: np.ndarray, R: np.ndarray, z: np.ndarray) -> Gaussian:
    m, P, _ = kalman_update(g.m, g.P, H, R, z)
    return Gaussian(m, P)


@RULES.register(LinearGaussianLikelihood, Gaussian)
def _update_gaussian(ctx: RuleContext, factor, frame) -> None:
    var = factor.variables[0]
    z = _measurement(factor, frame)
    if z is not None:
        ctx.beliefs[var] = _kalman_update(ctx.beliefs[var], factor.H, factor.R, z)


@RULES.register("estimate", Gaussian)
def _estimate_gaussian(ctx: RuleContext, variable: str, frame) -> np.ndarray:
    return ctx.beliefs[variable].m


@RULES.register("resample", Gaussian)
def _no_resample_gaussian(ctx: RuleContext, variable: str, frame) -> None:
    return None


# -- the VB adaptive Kalman filter ------------------------------------------------------------
def gaussian_elbo_terms(g: Gaussian, prior: Gaussian, q: InverseGamma, q_pred: InverseGamma,
                        H: np.ndarray, z: np.ndarray) -> float:
    """ELBO of the VB-AKF: ``E_q[log N(z; Hx, R)] − KL(q(x)‖p(x)) − KL(q(R)‖p(R))``."""
    r = z - H @ g.m
    hph = np.diag(H @ g.P @ H.T)
    expected_loglik = (-0.5 * z.size * np.log(2 * np.pi) - 0.5 * q.expected_log_variance().sum()
                       - 0.5 * np.sum(q.expected_precision() * (r * r + hph)))
    return float(expected_loglik - g.kl(prior) - q.kl(q_pred))


def vb_akf_update(prior: Gaussian, q_pred: InverseGamma, H: np.ndarray, z: np.ndarray,
                  tol: float, max_iter: int) -> tuple[Gaussian, InverseGamma, VBInfo]:
    """The VB-AKF fixed point of one Gaussian (:func:`pgm.inference.kalman.vb_akf_batch`),
    with the ELBO of each iteration and of the result."""
    elbo: list[float] = []

    def record(m, P, alpha, beta):
        elbo.append(gaussian_elbo_terms(Gaussian(m[0], P[0]), prior,
                                        InverseGamma(alpha[0], beta[0]), q_pred, H, z))

    m, P, alpha, beta, it = vb_akf_batch(prior.m[None], prior.P[None],
                                         q_pred.alpha[None], q_pred.beta[None], H, z[None],
                                         tol, max_iter, on_iteration=record)
    g, q = Gaussian(m[0], P[0]), InverseGamma(alpha[0], beta[0])
    elbo.append(gaussian_elbo_terms(g, prior, q, q_pred, H, z))
    return g, q, VBInfo(iterations=it, elbo=elbo, r_hat=q.r_hat())


def _vb_likelihood(ctx: RuleContext, factor):
    """The one likelihood a :class:`VBNoise` factor parameterises (untied)."""
    liks = [f for f in ctx.graph.factors_of(factor.variables[1], "likelihood")
            if factor.likelihood in (None, f.name)]
    if len(liks) != 1:
        raise vb_likelihood_refusal(factor, ctx.graph)
    if getattr(factor, "tie", None) is not None:
        raise ValueError(f"factor {factor.name!r}: tied noise components are implemented "
                         f"for the VB-PHD (Intensity) rule only")
    return liks[0]


@RULES.register(VBNoise, Gaussian)
def _vb_gaussian(ctx: RuleContext, factor, frame) -> VBInfo | None:
    noise, target = factor.variables
    liks = [_vb_likelihood(ctx, factor)]
    z = _measurement(liks[0], frame)
    if z is None:
        return None
    g, q, info = vb_akf_update(ctx.beliefs[target], ctx.beliefs[noise], liks[0].H, z,
                               factor.tol, factor.max_iter)
    ctx.beliefs[target], ctx.beliefs[noise] = g, q
    return info


# -- mean-field VB on particles: any likelihood that gives its noise residuals ----------------
@dataclass
class VBParticleState:
    """The beliefs this frame's VB fixed point started from (``frame``: its index), so that
    a second in-frame pass restarts from them instead of updating twice."""

    frame: int | None = None
    before: tuple[Any, Any] | None = None


def _expected_loglik(r2: np.ndarray, q: InverseGamma) -> np.ndarray:
    """``E_q(σ²)[log N(r; 0, diag σ²)]`` per particle from squared residuals ``(N, k)``."""
    return -0.5 * (r2.shape[1] * np.log(2 * np.pi) + q.expected_log_variance().sum()
                   + r2 @ q.expected_precision())


@RULES.register(VBNoise, Particles)
def _vb_particles(ctx: RuleContext, factor, frame) -> VBInfo | None:
    """Mean-field VB between a particle belief ``q(x)`` and an inverse-Gamma noise belief
    ``q(σ²)`` for a likelihood with the conjugate contract (``noise_residuals(x, frame)``:
    residuals with independent Gaussian noise of variances ``σ²``). Coordinate ascent:
    ``q(x)`` reweights the predicted particles by ``exp E_q(σ²)[log p(y | x, σ²)]``;
    ``q(σ²_j) = IG(α̂_j + 1/2, β̂_j + E_q(x)[r_j²] / 2)``; until ``R̂ = β/α`` moves by less
    than ``tol`` (relative) or ``max_iter`` passes; the ELBO of each pass is recorded
    (non-decreasing: each step maximises it in one factor)."""
    noise, target = factor.variables
    lik = _vb_likelihood(ctx, factor)
    residuals = getattr(lik, "noise_residuals", None)
    if residuals is None:
        raise ValueError(f"factor {factor.name!r}: likelihood {lik.name!r} gives no "
                         f"noise_residuals(x, frame), the conjugate contract of VB over its "
                         f"noise (pgm.inference.vb)")
    state = ctx.state.get(factor.name, VBParticleState)
    if state.frame != frame.index:  # the frame's first pass: keep where it starts
        state.frame, state.before = frame.index, (ctx.beliefs[target], ctx.beliefs[noise])
    b0, q_pred = state.before
    r = residuals(b0.x, frame)
    if r is None:
        return None
    r2 = np.asarray(r, dtype=float) ** 2
    if r2.shape != (b0.num, q_pred.dim):
        raise ValueError(f"factor {factor.name!r}: {lik.name!r} gave residuals of shape "
                         f"{r2.shape}, expected ({b0.num}, {q_pred.dim}) (one per noise "
                         f"component)")
    lw0 = b0.log_weights - b0.log_mass
    q, elbo, it = q_pred, [], 0
    for it in range(1, factor.max_iter + 1):  # noqa: B007 - the count is reported
        lw = lw0 + _expected_loglik(r2, q)
        w = np.exp(lw - lw.max())
        w /= w.sum()
        new = InverseGamma(q_pred.alpha + 0.5, q_pred.beta + 0.5 * (w @ r2))
        ell = _expected_loglik(r2, new)
        kl_x = float(np.sum(w * (np.log(np.maximum(w, 1e-300)) - lw0)))
        elbo.append(float(w @ ell) - kl_x - new.kl(q_pred))
        change = np.max(np.abs(new.r_hat() - q.r_hat()) / q.r_hat())
        q = new
        if change < factor.tol:
            break
    # ``ell`` is already the expected log-likelihood under the final ``q``
    ctx.beliefs[target] = b0.reweight(ell).normalized()
    ctx.evidence[target] = (b0.log_weights, ell)
    ctx.beliefs[noise] = q
    return VBInfo(iterations=it, elbo=elbo, r_hat=q.r_hat())


# -- the VB-PHD filter ------------------------------------------------------------------------
def tie_matrix(factor, k: int) -> tuple[np.ndarray | None, np.ndarray | float, np.ndarray]:
    """``(T, counts, reps)`` of a :class:`VBNoise` factor's tied components: ``T[i, j] = 1``
    where components ``i`` and ``j`` share one variance, ``counts`` the size of each
    component's group and ``reps`` one component per group; ``(None, 1.0, all)`` untied."""
    tie = getattr(factor, "tie", None)
    if tie is None:
        return None, 1.0, np.arange(k)
    tie = np.asarray(tie)
    if tie.shape != (k,):
        raise ValueError(f"factor {factor.name!r}: tie has {tie.size} entries for {k} "
                         f"measurement components")
    T = (tie[:, None] == tie[None, :]).astype(float)
    return T, T.sum(axis=0), np.unique(tie, return_index=True)[1]


def _kl_of(q: InverseGamma, p: InverseGamma, reps: np.ndarray) -> float:
    """``KL(q‖p)`` counting each tied group once (its components are equal)."""
    if reps.size == q.dim:
        return q.kl(p)
    return InverseGamma(q.alpha[reps], q.beta[reps]).kl(InverseGamma(p.alpha[reps], p.beta[reps]))


def _noise_prior(ctx: RuleContext, noise: str) -> InverseGamma:
    priors = ctx.graph.factors_of(noise, "prior")
    if not priors:
        raise ValueError(f"noise variable {noise!r} needs a prior for per-track beliefs")
    return priors[0].belief()


def _vb_phd_fixed_point(ctx: RuleContext, factor, frame, inv: np.ndarray,
                        q_pred: list[InverseGamma]) -> dict[str, Any]:
    """The VB-PHD fixed point with one noise belief per group of particles.

    ``inv`` ``(N,)`` maps each persistent particle to its group; ``q_pred`` holds each
    group's predicted belief. One group is the shared-noise filter (the default; Algorithm
    1 of [#feng2015] carries ``(α, β)`` per particle); one group per lineage label is the
    per-track option. Each group's statistics are
    summed over its own particles (``np.bincount``: no loop over particles).
    """
    noise, target = factor.variables
    phd: PHDLikelihood = phd_factor_of(ctx, target)
    b: Intensity = ctx.beliefs[target]
    n_groups, k = len(q_pred), phd.H.shape[0]
    a_hat = np.array([q.alpha for q in q_pred]).reshape(n_groups, k)
    b_hat = np.array([q.beta for q in q_pred]).reshape(n_groups, k)
    # tied components share one variance: T (k, k) averages a group's prior and sums its
    # statistics; each measurement then counts once per tied component (tie_count)
    T, tie_count, reps = tie_matrix(factor, k)
    if T is not None:
        a_hat, b_hat = a_hat @ T / tie_count, b_hat @ T / tie_count
        q_pred = [InverseGamma(a_hat[g], b_hat[g]) for g in range(n_groups)]
    z = phd.measurements(frame)
    w_pred = np.exp(b.log_weights) if b.num else np.zeros(0)
    mass = np.bincount(inv, weights=w_pred, minlength=n_groups)
    # first pass: sum_z W_z unknown -> min(|Z|, p_D x predicted mass), beta = beta_hat
    alpha = a_hat + 0.5 * np.minimum(z.shape[0], phd.p_detect * mass)[:, None] * tie_count
    beta = b_hat.copy()
    sq_dist = phd.sq_dist(b.x, z)  # (k, M, N), once per frame: reused by every iteration
    elbo: list[float] = []
    res: dict[str, Any] = {}
    r_hat = beta / alpha
    it = 0
    for it in range(1, factor.max_iter + 1):  # noqa: B007 - the count is reported
        qs = [InverseGamma(alpha[g], beta[g]) for g in range(n_groups)]  # loop over groups
        prec = np.array([q.expected_precision() for q in qs]).reshape(n_groups, k)
        logv = np.array([q.expected_log_variance() for q in qs]).reshape(n_groups, k)
        if n_groups == 1:  # one shared belief: (k,) vectors, no per-particle copies
            res = _update(ctx, target, phd, frame, prec[0], logv[0], sq=sq_dist)
        else:
            res = _update(ctx, target, phd, frame, prec[inv], logv[inv], sq=sq_dist)
        elbo.append(float(np.sum(np.log(res["L"])))  # KL once per tied group
                    - sum(_kl_of(q, p, reps) for q, p in zip(qs, q_pred, strict=True)))
        omega, W = res["omega"], res["W"]
        if factor.strict_counts:
            omega = omega * (W >= 0.5)[None, :]
        sq = np.zeros_like(beta)
        om = np.ascontiguousarray(omega.T)  # (M, N), a view of the corrector's buffer
        if n_groups == 1:  # shared noise: plain sums
            alpha = a_hat + 0.5 * omega.sum() * tie_count
            for i in range(k):  # k components, vectorised over particles x measurements
                sq[0, i] = np.vdot(om, sq_dist[i])
        else:
            alpha = a_hat + 0.5 * np.bincount(inv, weights=omega.sum(axis=1),
                                              minlength=n_groups)[:, None] * tie_count
            for i in range(k):
                sq[:, i] = np.bincount(inv, weights=np.einsum("mn,mn->n", om, sq_dist[i]),
                                       minlength=n_groups)
        beta = b_hat + 0.5 * (sq if T is None else sq @ T)
        new_r = beta / alpha
        change = float(np.max(np.abs(new_r - r_hat) / r_hat)) if new_r.size else 0.0
        r_hat = new_r
        if change < factor.tol:
            break
    post = np.bincount(inv, weights=res["w"], minlength=n_groups) if b.num else mass
    return {"iterations": it, "elbo": elbo, "alpha": alpha, "beta": beta, "r_hat": r_hat,
            "res": res, "mass": post}


def _vb_phd_per_track(ctx: RuleContext, factor, frame) -> VBInfo:
    """VB-PHD with one inverse-Gamma belief per lineage label (``per_track=True``)."""
    noise, target = factor.variables
    phd: PHDLikelihood = phd_factor_of(ctx, target)
    b: Intensity = ctx.beliefs[target]
    state = ctx.state.get(target, PHDState)
    if b.labels is None:
        b = Intensity(b.x, b.log_weights, (), newborn=b.newborn,
                      labels=np.zeros(b.num, dtype=np.int64))
        ctx.beliefs[target] = b
        if state.next_label is None:
            state.next_label = 1
    prior = _noise_prior(ctx, noise)
    forget = ctx.graph.factors_of(noise, "transition")
    known: dict[int, InverseGamma] = state.noise_by_label or {}
    uniq, inv = np.unique(b.labels, return_inverse=True)
    q_pred = []
    for lab in uniq.tolist():  # a loop over tracks (labels), not particles
        q = known.get(lab)
        if q is None:
            q_pred.append(prior)
        else:
            q_pred.append(q.forget(forget[0].rho, forget[0].alpha_min) if forget else q)
    out = _vb_phd_fixed_point(ctx, factor, frame, inv, q_pred)
    alpha, beta, r_hat, post_mass = out["alpha"], out["beta"], out["r_hat"], out["mass"]
    state.noise_by_label = {lab: InverseGamma(alpha[g], beta[g])
                             for g, lab in enumerate(uniq.tolist())}
    if post_mass.sum() > 0:
        summary = (post_mass[:, None] * r_hat).sum(axis=0) / post_mass.sum()
    else:
        summary = prior.r_hat()
    _finish(ctx, target, phd, out["res"], prior.r_hat())
    state.r_hat = summary
    ctx.beliefs[noise] = InverseGamma(prior.alpha, prior.alpha * summary)
    return VBInfo(iterations=out["iterations"], elbo=out["elbo"], r_hat=summary,
                  tracks=len(uniq),
                  r_hat_by_label={lab: r_hat[g] for g, lab in enumerate(uniq.tolist())})


@RULES.register(VBNoise, Intensity)
def _vb_phd(ctx: RuleContext, factor, frame) -> VBInfo:
    if getattr(factor, "per_track", False):
        return _vb_phd_per_track(ctx, factor, frame)
    noise, target = factor.variables
    b: Intensity = ctx.beliefs[target]
    out = _vb_phd_fixed_point(ctx, factor, frame, np.zeros(b.num, dtype=np.int64),
                              [ctx.beliefs[noise]])
    q = InverseGamma(out["alpha"][0], out["beta"][0])
    ctx.beliefs[noise] = q
    _finish(ctx, target, phd_factor_of(ctx, target), out["res"], q.r_hat())
    ctx.state.get(target, PHDState).r_hat = q.r_hat()
    return VBInfo(iterations=out["iterations"], elbo=out["elbo"], r_hat=q.r_hat())
