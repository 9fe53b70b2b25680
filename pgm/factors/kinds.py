"""The kind base classes of factors: prior, transition, likelihood, coupling, conjugate.

Subclass one of them to declare a new factor; :class:`~pgm.core.factor.Factor` (the
root) registers every concrete subclass by name so that saved graphs load without code.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

import numpy as np

from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.variable import Variable

__all__ = ["PriorFactor", "TransitionFactor", "LikelihoodFactor", "CouplingFactor",
           "ConjugateFactor", "ProposalFactor"]


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

    def born_at(self, values: dict[str, float], labels) -> PriorFactor:
        """This prior re-centred on a new target: the components named in ``values``
        (e.g. ``cx, cy, w, h``) set, for a plate replica born on a detection."""
        raise ValueError(f"prior {self.name!r} ({type(self).__name__}) cannot be re-centred "
                         f"on a new target; give it a born_at method")


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

    def log_prob_columns(self, x: np.ndarray, columns, *past: np.ndarray) -> np.ndarray:
        """``log p(x_t[columns] | past)``, the marginal density of some components, shape
        ``(N,)``: what a proposal of those components only is corrected by (the others
        drawn from this transition, so their density cancels). Valid where the
        transition draws ``columns`` independently of the other components given the
        past; the default covers ``columns`` None (every component)."""
        if columns is None or sorted(columns) == list(range(x.shape[1])):
            return self.log_prob(x, *past)
        raise ValueError(f"{type(self).__name__} does not give the marginal density of "
                         f"components {list(columns)} (define log_prob_columns)")


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
    :mod:`pgm.factors.couplings`.
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


class ProposalFactor(Factor):
    r"""A proposal ``q(x_t | x_{t-1}, z_t)`` for one variable's particles (kind
    ``"proposal"``), used by the predict stage in place of the transition for a share
    ``fraction`` of the particles.

    The engine draws ``round(fraction · N)`` particles from :meth:`sample` and the rest
    from the variable's transition, and corrects every particle's weight by the
    deterministic-mixture ratio

    .. math::
        w \leftarrow w \, \frac{p(x_t \mid x_{t-1})}
                                  {(1 - f)\, p(x_t \mid x_{t-1}) + f\, q(x_t \mid x_{t-1}, z_t)}

    (the transition's :meth:`TransitionFactor.log_prob` and this factor's
    :meth:`log_prob`), so the weighted particles stay an unbiased approximation of the
    same posterior whatever ``q`` is; a ``q`` close to the posterior lowers the weights'
    variance, and ``fraction < 1`` keeps the transition's support (a defensive mixture).
    """

    kind = "proposal"
    abstract = True

    def __init__(self, variable: str, *, fraction: float = 1.0, columns=None,
                 name: str | None = None):
        super().__init__(variable, name=name)
        f = float(fraction)
        if not 0.0 < f <= 1.0:
            raise ValueError(f"factor {self.name!r}: fraction must be in (0, 1], got "
                             f"{fraction!r}")
        self.fraction = f
        #: the components it proposes (None: all); the others come from the transition,
        #: and the weight correction uses the transition's marginal density of these
        #: (:meth:`TransitionFactor.log_prob_columns`) against :meth:`log_prob`, which is
        #: then the density of these components only
        self.columns: tuple[int, ...] | None = None
        if columns is not None:
            cols = tuple(int(c) for c in columns)
            if not cols or len(set(cols)) != len(cols) or min(cols) < 0:
                raise ValueError(f"factor {self.name!r}: columns must be distinct component "
                                 f"indices, got {columns!r}")
            self.columns = cols

    @abstractmethod
    def sample(self, rng: np.random.Generator, ctx: FrameContext,
               *past: np.ndarray) -> np.ndarray:
        """Draw one particle per row of ``past[0]`` (``x_{t-1}``, shape ``(N, d)``)."""

    @abstractmethod
    def log_prob(self, x: np.ndarray, ctx: FrameContext, *past: np.ndarray) -> np.ndarray:
        """``log q(x_t | past, z_t)``, shape ``(N,)``."""

    def prepare(self, ctx: FrameContext, past: tuple[np.ndarray, ...], *,
                confidence: float | None, factors: dict[str, Factor]) -> float:
        """This frame's share of proposed particles, called before :meth:`sample`
        (default: :attr:`fraction`). ``confidence`` is the graph's calibrated confidence
        at the previous frame (:func:`pgm.core.readout.confidence`; None where it declares
        none), ``factors`` the graph's factors by name. Returning 0 skips the proposal
        for this frame (every particle from the transition); the share must not depend on
        this frame's draws, so the weights stay correct. A proposal may also compute
        here what :meth:`sample` and :meth:`log_prob` share in this frame."""
        return self.fraction
