"""Gaussian-process dynamical model (GPDM) of box motion: learning, storage, prediction.

Wang, Yin & Man [#wang2008] learn a GPDM (Wang, Fleet & Hertzmann, TPAMI 2008) of
people's frame-to-frame coordinate changes and draw a particle filter's proposals from
it. A prototype of the paper's recipe has *no finite MAP minimum* (observation noise → 0,
the latent shrinking, dynamics noise → 0) and never beat constant velocity. This module
implements the model with the fixes that this requires, and says where it departs from
the paper:

* **Observation** ``y_t = (Δcx, Δtop, Δh) / h_{t-1} · fps`` — the box's centre-x, top
  and height changes in *box heights per second* (:func:`box_differences`), not the
  paper's 6-D head/centroid/feet differences in pixels per frame (that vector has rank
  3; the three x-differences coincide and the y's are linear in ``Δtop`` and ``Δh``).
  ``Y`` is standardised (``ȳ`` and the per-dimension standard deviation kept) and the
  paper's scale matrix ``W`` is fixed to the identity (``W = 1``), so the ``tr(W²)/2κ²``
  and ``−N ln|W|`` terms vanish.
* **Bounded hyper-parameters.** The noise variances ``β₂⁻¹`` and ``α₄⁻¹`` have floors
  relative to the data variance (:attr:`GPDMSettings.obs_noise_floor` × 1 for the
  standardised ``Y``; :attr:`GPDMSettings.dyn_noise_floor` × 1 for the latent, which is
  initialised with unit mean square); every other hyper-parameter lives in a box
  (:data:`HYPER_BOUNDS`) through a logistic transform of its logarithm. The inverse
  squared length-scales ``α₂, β₁`` are capped at 10 (length-scale ≥ 0.32 of the unit
  latent scale): without the cap ``β₁`` keeps growing (GP-LVM overfitting — each
  training point gets its own basin) and held-out prediction worsens the longer L-BFGS
  runs (measured on the planted-dynamics test: one-step RMSE 0.07 at 50 iterations,
  0.09 at 300 with ``β₁ = 19.5``; with the cap 0.074 at 300). The paper's
  improper prior ``Σ ln α_j + Σ ln β_j`` is kept, but it has no minimum either (each
  term runs to −∞ as its parameter → 0 while the kernel stays finite), so without the
  box it would be one more unbounded direction.
* **A fixed latent scale** (:attr:`GPDMSettings.latent_scale`): ``"unit"`` (default)
  parametrises ``X = Z · sqrt(N d / ‖Z‖²)``, so the latent's mean square is 1 by
  construction and the shrinking direction does not exist; ``"prior"`` puts an
  ``N(0, I)`` prior on every latent point instead (it subsumes the paper's prior on each
  sequence's first point). *Measured:* the prior alone does not fix the scale — shrinking
  ``X`` lowers the prior term too, so the latent shrinks until the dynamics-noise floor
  stops it, the kernels turn narrow, and one-step error on the planted-dynamics test
  doubles between 50 and 200 L-BFGS iterations; ``"unit"`` has no such drift. Optionally
  the dynamics hyper-parameters are *fixed* (:attr:`GPDMSettings.fix_dynamics`, Wang et
  al. 2008's remedy for this overfitting: ``α₁ = 1, α₂ = 1, α₃ = 0.1`` in the unit-scale
  latent, ``α₄⁻¹ = max(dyn_noise_floor, 0.01)``; our values).
* **A stopping rule**: L-BFGS (torch autograd, float64, strong-Wolfe line search) in
  rounds of :attr:`GPDMSettings.check_every` iterations, stopped when the objective's
  relative change over a round falls below :attr:`GPDMSettings.rel_tol` or after
  :attr:`GPDMSettings.max_iter` iterations. The paper's SCG is not used.
* **Several sequences as one GP**: each trajectory's ``(X_in, X_out)`` pairs are
  concatenated (``N − S`` rows for ``S`` sequences); no dynamics pair crosses a
  boundary. Long training sets are cut into chunks and a random subset of chunks
  (:attr:`GPDMSettings.max_points` points, drawn with the ``numpy`` Generator passed
  in) is kept, as the exact GP costs ``O(N³)``.
* **Mirroring** (:attr:`GPDMSettings.mirror`): every training trajectory is added again
  with ``Δcx`` negated, removing the scene's mean horizontal flow (the prototype found
  rollouts drifting back to the training scene's ``ȳ``).
* **Balanced GPDM** (:attr:`GPDMSettings.balanced`): ``L_X`` is multiplied by ``D/d``.
* **Test-time latent** from the last :attr:`GPDMSettings.history` differences, not one
  and not the PCA projection: the latent path ``z_1..z_K`` maximising
  ``Σ_k log N(y_k; μ_Y(z_k), σ²_Y(z_k)) + Σ_k log N(z_k; μ_X(z_{k−1}), σ²_X(z_{k−1}))``
  (plus the latent prior), started from the best-scoring window of ``K`` consecutive
  training latents and refined by a few L-BFGS iterations; its last point is the
  current latent (:meth:`GPDM.infer_latent`).
* **Constant-velocity fallback**: with fewer than :attr:`GPDMSettings.min_history`
  boxes (track birth) :func:`predict` returns :func:`predict_constant_velocity`.

Model (``W = 1``, latent dimension ``d``, observation dimension ``D = 3``)::

    k_Y(x, x') = exp(−β₁/2 ‖x − x'‖²) + β₂⁻¹ δ
    k_X(x, x') = α₁ exp(−α₂/2 ‖x − x'‖²) + α₃ xᵀx' + α₄⁻¹ δ
    L = (D/2) ln|K_Y| + ½ tr(K_Y⁻¹ Y Yᵀ)
        + c [(d/2) ln|K_X| + ½ tr(K_X⁻¹ X_out X_outᵀ)]      (c = D/d if balanced, else 1)
        + ½ Σ_i ‖x_i‖²  ("prior")  or  ½ Σ_starts ‖x_1‖²  ("unit": ‖X‖² = N d fixed)
        + Σ_j ln α_j + Σ_j ln β_j
    μ_X(x) = X_outᵀ K_X⁻¹ k_X(x),  σ²_X(x) = k_X(x, x) − k_X(x)ᵀ K_X⁻¹ k_X(x)  (α₄⁻¹ included)
    μ_Y(x) = ȳ + s ⊙ Yᵀ K_Y⁻¹ k_Y(x)                           (Y standardised: ȳ, s)

``δ`` is a Kronecker delta on training indices, so a new point's cross-covariance has no
noise term and its self-covariance has it.

Prediction (:func:`predict`) samples latent particles ``z ← N(μ_X(z), σ²_X(z) I)`` and
maps each through ``μ_Y`` to a box change; vectorised over particles. The per-target
chain with shared learned dynamics departs from the paper, which stacks all ``n``
targets into one ``6n``-dimensional vector.

A learned model is stored as ``.npz`` (arrays and a JSON header; no pickle) by
:meth:`GPDM.save` and read back, validated, by :func:`load_gpdm`. ``pgm learn gpdm``
maps onto :func:`gt_trajectories` + :func:`learn_gpdm` + :meth:`GPDM.save`; a model
config loads the file with :func:`load_gpdm` and calls :func:`predict` or the
vectorised :meth:`GPDM.dynamics` / :meth:`GPDM.mean_y` directly.

References
----------
.. [#wang2008] J. Wang, Y. Yin and H. Man, "Multiple human tracking using particle filter with
   Gaussian process dynamical model", EURASIP J. Image and Video Processing 2008, Article
   ID 969456. doi:10.1155/2008/969456
"""

from __future__ import annotations

from .gpdm_data import Trajectory, apply_differences, box_differences, gt_trajectories
from .gpdm_learn import fit_gpdm, learn_gpdm
from .gpdm_model import (
    _ARRAYS,
    FIXED_DYNAMICS,
    FORMAT,
    GPDM,
    HYPER_BOUNDS,
    LATENT_SCALES,
    NOISE_UPPER,
    VERSION,
    GPDMSettings,
    dynamics_kernel,
    load_gpdm,
    observation_kernel,
)
from .gpdm_predict import predict, predict_constant_velocity

__all__ = ["GPDM", "GPDMSettings", "Trajectory", "HYPER_BOUNDS", "FIXED_DYNAMICS",
           "apply_differences", "box_differences", "dynamics_kernel", "fit_gpdm",
           "gt_trajectories", "learn_gpdm", "load_gpdm", "observation_kernel", "predict",
           "predict_constant_velocity", "FORMAT", "VERSION", "NOISE_UPPER", "LATENT_SCALES",
           "_ARRAYS"]
