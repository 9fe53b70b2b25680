r"""A motion library in physical units: random walk, constant velocity, constant
acceleration, Singer and coordinated turn, on any state layout.

Each model is a continuous-time linear stochastic differential equation per *axis*
(a position and its derivatives), ``dx = A x dt + L dβ`` with white noise ``β`` of
spectral density ``q`` (variance per second of the highest derivative's increments), and
the factor is its exact discretisation at the video's frame interval ``dt = 1 / fps``
(Van Loan's matrix exponential, :func:`discretize`): ``x_t = F x_{t-1} + N(0, Q)``. So a
model's constants are in seconds and carry between frame rates: the same ``q`` at 10 and
30 frames/s gives the same uncertainty after one second (the discretisation composes
exactly, ``F(a+b) = F(b) F(a)``, ``Q(a+b) = F(b) Q(a) F(b)ᵀ + Q(b)``; tested).

* ``random-walk`` — one axis: the position; ``q``: its variance per second;
* ``constant-velocity`` — position, velocity; ``q``: the acceleration's spectral density;
* ``constant-acceleration`` — position, velocity, acceleration; ``q``: the jerk's;
* ``singer`` — position, velocity, acceleration, the acceleration an Ornstein-Uhlenbeck
  process (Singer 1970) of sd ``sigma`` and correlation time ``tau`` seconds;
* ``coordinated-turn`` — two axes ``(x, vx), (y, vy)``, the velocity turning at a known
  ``turn_rate`` rad/s (Li & Jilkov 2003), ``q`` as for constant velocity.

:class:`MotionTransition` is a :class:`~pgm.factors.gaussian.LinearGaussianTransition`,
so every rule of one serves it: particles, exact Gaussian (Kalman) beliefs, plates of
either (the SORT family's Kalman replicas included). Its saved form holds the physical
constants, not ``F`` and ``Q``. Components of the variable in no axis (a box's width and
height, say) stay put, with a random walk of ``q_static`` per second if given.

>>> f = constant_velocity("box", labels=("cx", "cy", "vx", "vy"),
...                       axes=[("cx", "vx"), ("cy", "vy")], q=4.0, fps=10)
>>> f.F[0].tolist(), round(float(f.Q[2, 2]), 6)
([1.0, 0.0, 0.1, 0.0], 0.4)

References: R. A. Singer, "Estimating optimal tracking filter performance for manned
maneuvering targets", IEEE Trans. Aerospace and Electronic Systems 6(4), 1970; X. R. Li and
V. P. Jilkov, "Survey of maneuvering target tracking. Part I: dynamic models", IEEE Trans.
Aerospace and Electronic Systems 39(4), 2003; C. F. Van Loan, "Computing integrals
involving the matrix exponential", IEEE Trans. Automatic Control 23(3), 1978.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from pgm.core.numerics import check_finite_param

from .gaussian import LinearGaussianTransition

__all__ = ["MOTION_MODELS", "MotionTransition", "discretize", "axis_model", "random_walk",
           "constant_velocity", "constant_acceleration", "singer", "coordinated_turn"]

#: the models, with the number of components of one axis (coordinated turn: two axes of 2)
MOTION_MODELS = {"random-walk": 1, "constant-velocity": 2, "constant-acceleration": 3,
                 "singer": 3, "coordinated-turn": 2}


def discretize(A: np.ndarray, noise: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:  # noqa: N803
    """``(F, Q)`` of ``dx = A x dt + dw`` (``dw``: white noise of spectral density matrix
    ``noise``) over ``dt`` seconds: ``F = exp(A dt)``, ``Q = ∫₀^dt exp(As) noise
    exp(As)ᵀ ds``, both exactly by one matrix exponential (Van Loan 1978)."""
    from scipy.linalg import expm

    A = np.atleast_2d(np.asarray(A, dtype=float))  # noqa: N806
    n = A.shape[0]
    m = np.zeros((2 * n, 2 * n))
    m[:n, :n] = -A
    m[:n, n:] = noise
    m[n:, n:] = A.T
    e = expm(m * dt)
    F = e[n:, n:].T  # noqa: N806
    Q = F @ e[:n, n:]  # noqa: N806
    return F, 0.5 * (Q + Q.T)


def axis_model(model: str, *, q: float = 0.0, sigma: float = 0.0, tau: float = 1.0,
               turn_rate: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(A, noise)`` of one axis (``coordinated-turn``: both axes, ``(x, vx, y, vy)``)."""
    if model == "random-walk":
        return np.zeros((1, 1)), np.array([[q]])
    if model == "constant-velocity":
        return np.array([[0.0, 1.0], [0.0, 0.0]]), np.diag([0.0, q])
    if model == "constant-acceleration":
        A = np.diag([1.0, 1.0], k=1)  # noqa: N806
        return A, np.diag([0.0, 0.0, q])
    if model == "singer":  # the acceleration an Ornstein-Uhlenbeck process of sd sigma
        A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0 / tau]])  # noqa: N806
        return A, np.diag([0.0, 0.0, 2.0 * sigma ** 2 / tau])
    if model == "coordinated-turn":  # velocity rotating at turn_rate, plus CV noise
        w = turn_rate
        A = np.zeros((4, 4))  # noqa: N806
        A[0, 1] = A[2, 3] = 1.0
        A[1, 3], A[3, 1] = -w, w
        return A, np.diag([0.0, q, 0.0, q])
    raise ValueError(f"unknown motion model {model!r} (one of {', '.join(MOTION_MODELS)})")


class MotionTransition(LinearGaussianTransition):
    """A motion model of :data:`MOTION_MODELS` on the components ``axes`` of a variable
    whose components are named ``labels``, discretised at ``fps`` frames per second.

    Parameters
    ----------
    variable : str
    model : str
        One of :data:`MOTION_MODELS`.
    labels : sequence of str
        The variable's component names (its ``Variable.labels``).
    axes : sequence of sequences of str
        Each axis's components, position first (``("cx", "vx")`` for constant velocity);
        coordinated turn takes exactly two axes of two.
    fps : float
        Frames per second of the video (``dt = 1 / fps``).
    q, sigma, tau, turn_rate : float
        The model's constants, per second (module docstring).
    q_static : float
        Random-walk variance per second of the components in no axis (0: they stay put).
    p_survive : float
        As for :class:`~pgm.factors.gaussian.LinearGaussianTransition`.
    """

    def __init__(self, variable: str, *, model: str, labels: Sequence[str],
                 axes: Sequence[Sequence[str]], fps: float, q: float = 0.0,
                 sigma: float = 0.0, tau: float = 1.0, turn_rate: float = 0.0,
                 q_static: float = 0.0, p_survive: float = 1.0, name: str | None = None):
        if model not in MOTION_MODELS:
            raise ValueError(f"unknown motion model {model!r} (one of "
                             f"{', '.join(MOTION_MODELS)})")
        for key, value in (("fps", fps), ("q", q), ("sigma", sigma), ("tau", tau),
                           ("turn_rate", turn_rate), ("q_static", q_static)):
            check_finite_param(f"{variable}.{key}", value)
        if fps <= 0 or tau <= 0 or q < 0 or sigma < 0 or q_static < 0:
            raise ValueError(f"motion of {variable!r}: fps and tau must be positive, q, sigma "
                             f"and q_static non-negative")
        labels = [str(lab) for lab in labels]
        axes = [tuple(str(c) for c in axis) for axis in axes]
        size = MOTION_MODELS[model]
        if model == "coordinated-turn" and len(axes) != 2:
            raise ValueError(f"motion of {variable!r}: coordinated turn needs two axes "
                             f"(x, vx) and (y, vy), got {len(axes)}")
        used = [c for axis in axes for c in axis]
        unknown = [c for c in used if c not in labels]
        if unknown or len(set(used)) != len(used) or not axes:
            raise ValueError(f"motion of {variable!r}: axes {axes} must name distinct "
                             f"components of {labels} (unknown: {unknown})")
        if any(len(axis) != size for axis in axes):
            raise ValueError(f"motion of {variable!r}: a {model} axis has {size} components "
                             f"(position first), got {axes}")
        dt = 1.0 / float(fps)
        d = len(labels)
        F, Q = np.eye(d), np.zeros((d, d))  # noqa: N806
        static = [i for i, lab in enumerate(labels) if lab not in used]
        Q[static, static] = q_static * dt
        A, noise = axis_model(model, q=q, sigma=sigma, tau=tau, turn_rate=turn_rate)  # noqa: N806
        fa, qa = discretize(A, noise, dt)
        groups = [[c for axis in axes for c in axis]] if model == "coordinated-turn" else axes
        for group in groups:
            idx = [labels.index(c) for c in group]
            F[np.ix_(idx, idx)] = fa
            Q[np.ix_(idx, idx)] = qa
        self.model, self.labels, self.axes, self.fps = model, tuple(labels), axes, float(fps)
        self.q, self.sigma, self.tau, self.turn_rate = float(q), float(sigma), float(tau), \
            float(turn_rate)
        self.q_static = float(q_static)
        super().__init__(variable, F=F, Q=Q, p_survive=p_survive, name=name)

    def check(self, variables: dict[str, Any]) -> None:
        """The dimension (as every linear-Gaussian transition), and the labels the motion
        was laid out by must be the variable's own, in its order: another order would put
        the motion on other components, silently."""
        super().check(variables)
        own = variables[self.variables[0]].labels
        if own is not None and tuple(own) != self.labels:
            raise ValueError(f"factor {self.name!r}: the motion is laid out over labels "
                             f"{list(self.labels)} but variable {self.variables[0]!r} has "
                             f"labels {list(own)} (give the variable's labels, in its order)")

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"model": self.model, "labels": list(self.labels),
                             "axes": [list(a) for a in self.axes], "fps": self.fps}
        defaults = {"q": 0.0, "sigma": 0.0, "tau": 1.0, "turn_rate": 0.0, "q_static": 0.0}
        p.update({k: getattr(self, k) for k, v in defaults.items() if getattr(self, k) != v})
        if self.p_survive != 1.0:
            p["p_survive"] = self.p_survive
        return p


def _motion(model: str, variable: str, **kw: Any) -> MotionTransition:
    return MotionTransition(variable, model=model, **kw)


def random_walk(variable: str, *, labels: Sequence[str], axes: Sequence[Sequence[str]],
                q: float, fps: float, **kw: Any) -> MotionTransition:
    """Each axis ``(position,)`` a random walk of variance ``q`` per second."""
    return _motion("random-walk", variable, labels=labels, axes=axes, q=q, fps=fps, **kw)


def constant_velocity(variable: str, *, labels: Sequence[str], axes: Sequence[Sequence[str]],
                      q: float, fps: float, **kw: Any) -> MotionTransition:
    """Each axis ``(position, velocity)``: white-noise acceleration of spectral density ``q``
    (``Q = q [[dt³/3, dt²/2], [dt²/2, dt]]``)."""
    return _motion("constant-velocity", variable, labels=labels, axes=axes, q=q, fps=fps,
                   **kw)


def constant_acceleration(variable: str, *, labels: Sequence[str],
                          axes: Sequence[Sequence[str]], q: float, fps: float,
                          **kw: Any) -> MotionTransition:
    """Each axis ``(position, velocity, acceleration)``: white-noise jerk of density ``q``."""
    return _motion("constant-acceleration", variable, labels=labels, axes=axes, q=q, fps=fps,
                   **kw)


def singer(variable: str, *, labels: Sequence[str], axes: Sequence[Sequence[str]],
           sigma: float, tau: float, fps: float, **kw: Any) -> MotionTransition:
    """Each axis ``(position, velocity, acceleration)`` with the acceleration an
    Ornstein-Uhlenbeck process of sd ``sigma`` and correlation time ``tau`` seconds."""
    return _motion("singer", variable, labels=labels, axes=axes, sigma=sigma, tau=tau,
                   fps=fps, **kw)


def coordinated_turn(variable: str, *, labels: Sequence[str], axes: Sequence[Sequence[str]],
                     turn_rate: float, q: float, fps: float, **kw: Any) -> MotionTransition:
    """Axes ``(x, vx), (y, vy)``: the velocity turning at ``turn_rate`` rad/s (known), with
    constant-velocity noise ``q``."""
    return _motion("coordinated-turn", variable, labels=labels, axes=axes, q=q,
                   turn_rate=turn_rate, fps=fps, **kw)
