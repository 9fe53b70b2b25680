"""The GPDM as factors of the generic engine: a prior and a transition over box + latent.

A tracker whose motion is a learned Gaussian-process dynamical model
(:mod:`pgm.dynamics.gpdm`, Wang, Yin & Man 2008) declares one variable per target,

    ``(cx, cy, w, h, z0, …, z{q−1})``

— the box centre and size in pixels and the target's ``q`` latent coordinates — with

* :class:`GPDMPrior`: the box at (or around) a birth box, the latent drawn uniformly
  from the model's training latents (plus a little jitter), so that the weights of the
  first frames select the latents whose predicted motion the frames confirm;
* :class:`GPDMTransition`: ``z' = μ_X(z) + s σ_X(z) ε`` and the box moved by
  ``y = μ_Y(z') (+ σ_Y(z') η)``, the box change in box heights per second, exactly as
  :func:`~pgm.dynamics.gpdm.apply_differences` moves a box.

Both name the model by the path of its ``.npz`` file (written by
:meth:`~pgm.dynamics.gpdm.GPDM.save`, e.g. by ``pgm learn gpdm``) and load it with
:func:`~pgm.dynamics.gpdm.load_gpdm` when they are built, so a saved graph declaration
(JSON) holds the path and reloads the model. A model file read once is kept (keyed by
its resolved path, modification time and size) and shared by every factor naming it:
a learned :class:`~pgm.dynamics.gpdm.GPDM` is immutable.

Randomness: every draw has the particle count as its leading axis and uses only
``standard_normal`` and ``random``, so a plate can split the draws of a
batched call per replica (:class:`pgm.inference.batched.ReplicaRNG`). Both factors
are vectorised over particles.
"""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError, one_line
from pgm.core.numerics import check_finite_param
from pgm.core.variable import Variable
from pgm.factors.kinds import PriorFactor, TransitionFactor

from .gpdm import GPDM, apply_differences, load_gpdm
from .gpdm_model import _torch_threads

__all__ = ["GPDMPrior", "GPDMTransition", "BOX_LABELS", "state_labels"]

#: labels of the box components, the first four of the state
BOX_LABELS = ("cx", "cy", "w", "h")
#: smallest width and height (px) a box entering the transition is given, so that a
#: degenerate particle cannot divide by zero
MIN_SIZE = 1e-6
#: model files read so far: (resolved path, mtime_ns, size) -> GPDM
_CACHE: dict[tuple[str, int, int], GPDM] = {}
_CACHE_SIZE = 8


def state_labels(latent_dim: int) -> tuple[str, ...]:
    """Labels of the state ``(cx, cy, w, h, z0, …, z{q−1})`` for ``q = latent_dim``."""
    return BOX_LABELS + tuple(f"z{k}" for k in range(int(latent_dim)))


def _model_path(owner: str, model: Any) -> str:
    if isinstance(model, (str, os.PathLike)) and str(model):
        return str(model)
    raise ValueError(f"factor {owner!r}: parameter 'model' must be the path of a GPDM "
                     f".npz file (pgm learn gpdm), got {model!r}")


def _load(owner: str, path: str) -> GPDM:
    """The GPDM in ``path`` (cached); an :class:`InputError` naming ``owner`` and the file."""
    p = Path(path)
    try:
        st = p.stat()
        key = (str(p.resolve()), st.st_mtime_ns, st.st_size)
    except OSError:
        key = None
    if key is not None and key in _CACHE:
        return _CACHE[key]
    try:
        model = load_gpdm(p)
    except ValueError as exc:  # InputError included: missing, corrupt, invalid
        raise InputError(f"factor {owner!r}: {one_line(exc)}") from None
    if key is not None:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = model
    return model


def _check_state(factor, variables: dict[str, Variable], model: GPDM, path: str) -> None:
    """The variable must be ``(cx, cy, w, h)`` plus the model's ``q`` latent coordinates."""
    var = factor.variables[0]
    q = model.latent_dim
    factor._check_dim(variables, var, 4 + q,
                      f"the GPDM state (cx, cy, w, h and the {q} latent coordinates of {path})")
    labels = variables[var].labels
    if labels is not None and tuple(labels[:4]) != BOX_LABELS:
        raise ValueError(f"factor {factor.name!r}: variable {var!r} must start with the box "
                         f"components {BOX_LABELS}, has labels {labels}")


def _bool_param(owner: str, name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"factor {owner!r}: parameter {name!r} must be true or false, got "
                         f"{value!r}")
    return bool(value)


class GPDMTransition(TransitionFactor):
    r"""One frame of a target's motion under a learned GPDM (order 1).

    For a particle ``(box, z)`` with ``box = (cx, cy, w, h)``:

    .. math::
        z' = \mu_X(z) + s\,\sigma_X(z)\,\varepsilon,\qquad
        y = \bar y + \mathrm{std}_y \odot (\tilde\mu_Y(z') + \sigma_Y(z')\,\eta)

    with ``ε ~ N(0, I_q)``, ``η ~ N(0, I_3)``, ``s = latent_noise_scale``, ``μ̃_Y`` and
    ``σ²_Y`` the standardised predictive mean and variance of the observation map
    (:meth:`GPDM.observe`) and ``(ȳ, std_y)`` the model's standardisation, so ``y`` is
    ``(Δcx, Δtop, Δh)`` in box heights per second. The new box is
    ``apply_differences(box, y, fps)``: each change times the previous height over
    ``fps``, the width scaled with the height (the aspect ratio is kept), the height at
    least 1 % of the previous one (boxes never invert). Returns ``(box', z')``.

    Parameters
    ----------
    variable : str
        A variable of dimension ``4 + q`` labelled ``cx, cy, w, h, z0, …``.
    model : str
        Path of a GPDM ``.npz`` file (:meth:`GPDM.save`); loaded here, stored as given.
    fps : float
        The video's frame rate (> 0).
    obs_noise : bool
        Add the observation map's predictive noise ``σ_Y(z') η`` (default); False: the
        box change is ``μ_Y(z')``.
    latent_noise_scale : float
        ``s ≥ 0``, multiplies ``σ_X`` (0: the mean latent path).
    name : str, optional

    Raises
    ------
    InputError
        (a ``ValueError``) naming the factor and the file when the model is missing or
        corrupt; ``ValueError`` for a bad parameter.
    """

    order = 1

    def __init__(self, variable: str, *, model: str, fps: float, obs_noise: bool = True,
                 latent_noise_scale: float = 1.0, name: str | None = None):
        super().__init__(variable, name=name)
        self.fps = float(check_finite_param(f"{self.name}.fps", fps, positive=True))
        self.obs_noise = _bool_param(self.name, "obs_noise", obs_noise)
        self.latent_noise_scale = float(check_finite_param(
            f"{self.name}.latent_noise_scale", latent_noise_scale, nonneg=True))
        self.model_path = _model_path(self.name, model)
        self.model = _load(self.name, self.model_path)

    def params(self) -> dict[str, Any]:
        return {"model": self.model_path, "fps": self.fps, "obs_noise": self.obs_noise,
                "latent_noise_scale": self.latent_noise_scale}

    def check(self, variables: dict[str, Variable]) -> None:
        _check_state(self, variables, self.model, self.model_path)

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        """Propagate particles ``past[0]`` of shape ``(n, 4 + q)``; returns ``(n, 4 + q)``.

        Draws ``rng.standard_normal((n, q))`` (when ``latent_noise_scale > 0``), then
        ``rng.standard_normal((n, 3))`` (when ``obs_noise``).
        """
        x = np.asarray(past[0], dtype=float)
        m = self.model
        q = m.latent_dim
        if x.ndim != 2 or x.shape[1] != 4 + q:
            raise ValueError(f"factor {self.name!r}: particles must have shape (n, {4 + q}), "
                             f"got {x.shape}")
        n = x.shape[0]
        if n == 0:
            return x.copy()
        with _torch_threads(1):  # small matrices: extra threads only contend (gpdm.py)
            mu_x, var_x = m.dynamics(x[:, 4:])
            z = mu_x
            if self.latent_noise_scale > 0:
                std = self.latent_noise_scale * np.sqrt(var_x)
                z = mu_x + std[:, None] * rng.standard_normal((n, q))
            mu_y, var_y = m.observe(z)
        if self.obs_noise:
            mu_y = mu_y + np.sqrt(var_y)[:, None] * rng.standard_normal((n, m.obs_dim))
        y = m.y_mean + m.y_std * mu_y
        box = x[:, :4].copy()
        box[:, 2:] = np.maximum(box[:, 2:], MIN_SIZE)
        return np.concatenate([apply_differences(box, y, self.fps), z], axis=1)


class GPDMPrior(PriorFactor):
    """Initial belief of a GPDM target: a box and a latent drawn from the training latents.

    The box is ``mean`` moved by ``box_std · h · N(0, 1)`` in ``cx`` and ``cy`` and
    scaled by ``exp(box_std · N(0, 1))`` in size (one factor for ``w`` and ``h``, the
    aspect ratio kept); ``box_std = 0`` puts every particle on ``mean``. The latent is a
    training latent point (a row of the model's ``X``) picked uniformly, plus
    ``latent_jitter · N(0, I_q)`` (the latent has unit mean square).

    Parameters
    ----------
    variable : str
        A variable of dimension ``4 + q`` labelled ``cx, cy, w, h, z0, …``.
    model : str
        Path of a GPDM ``.npz`` file; loaded here, stored as given.
    mean : array_like, shape (4,)
        The birth box ``(cx, cy, w, h)`` in pixels (positive size).
    box_std : float
        Position and log-size standard deviation as a fraction of the box height (≥ 0).
    latent_jitter : float
        Standard deviation of the jitter added to the picked training latent (≥ 0).
    name : str, optional
    """

    def __init__(self, variable: str, *, model: str, mean, box_std: float = 0.0,
                 latent_jitter: float = 0.05, name: str | None = None):
        super().__init__(variable, name=name)
        self.mean_ = self._box(mean)
        self.box_std = float(check_finite_param(f"{self.name}.box_std", box_std, nonneg=True))
        self.latent_jitter = float(check_finite_param(f"{self.name}.latent_jitter",
                                                      latent_jitter, nonneg=True))
        self.model_path = _model_path(self.name, model)
        self.model = _load(self.name, self.model_path)

    def _box(self, value) -> np.ndarray:
        box = np.asarray(value, dtype=float).reshape(-1)
        if box.shape != (4,):
            raise ValueError(f"factor {self.name!r}: mean must be a box (cx, cy, w, h), got "
                             f"{np.shape(value)} values")
        check_finite_param(f"{self.name}.mean", box)
        if np.any(box[2:] <= 0):
            raise ValueError(f"factor {self.name!r}: the mean box must have positive width and "
                             f"height, got {box.tolist()}")
        return box

    def params(self) -> dict[str, Any]:
        return {"model": self.model_path, "mean": self.mean_, "box_std": self.box_std,
                "latent_jitter": self.latent_jitter}

    def check(self, variables: dict[str, Variable]) -> None:
        _check_state(self, variables, self.model, self.model_path)

    def sample(self, rng: np.random.Generator, num: int) -> np.ndarray:
        """``num`` particles ``(num, 4 + q)``.

        Draws ``rng.standard_normal((num, 3))`` (when ``box_std > 0``), then
        ``rng.random(num)`` (the training latent, index ``floor(u · N)``), then
        ``rng.standard_normal((num, q))`` (when ``latent_jitter > 0``).
        """
        num = int(num)
        box = np.tile(self.mean_, (num, 1))
        if self.box_std > 0:
            e = rng.standard_normal((num, 3))
            box[:, :2] += (self.box_std * self.mean_[3]) * e[:, :2]
            box[:, 2:] *= np.exp(self.box_std * e[:, 2])[:, None]
        X = self.model.X
        idx = np.minimum((rng.random(num) * X.shape[0]).astype(np.int64), X.shape[0] - 1)
        z = np.array(X[idx], dtype=float)
        if self.latent_jitter > 0:
            z += self.latent_jitter * rng.standard_normal((num, X.shape[1]))
        return np.concatenate([box, z], axis=1)

    def mean(self) -> np.ndarray:
        """The box and the mean of the training latents, shape ``(4 + q,)``."""
        return np.concatenate([self.mean_, self.model.X.mean(axis=0)])

    def born_at(self, values: dict[str, float], labels: tuple[str, ...] | None = None
                ) -> GPDMPrior:
        """This prior re-centred on a new target's box.

        Parameters
        ----------
        values : dict
            New values of box components, keys among ``cx, cy, w, h``.
        labels : tuple of str, optional
            The variable's labels (a key must be one of them when given).

        Returns
        -------
        GPDMPrior
            Same name, model and noise; the named components of ``mean`` replaced (the
            model is shared, not reloaded).
        """
        box = self.mean_.copy()
        for key, val in values.items():
            if key not in BOX_LABELS:
                raise ValueError(f"prior {self.name!r}: can re-centre only the box components "
                                 f"{BOX_LABELS}, got {key!r}")
            if labels and key not in labels:
                raise ValueError(f"prior {self.name!r}: no component {key!r} in {tuple(labels)}")
            box[BOX_LABELS.index(key)] = float(val)
        new = copy.copy(self)
        new.mean_ = self._box(box)
        return new
