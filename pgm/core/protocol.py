"""The belief protocol: what every belief the engine keeps gives its rules, readouts,
drawings and tests, whatever its representation.

A *belief* (one variable of one graph: :class:`~pgm.Particles`, :class:`~pgm.Intensity`,
:class:`~pgm.core.expfam.Gaussian`, :class:`~pgm.core.expfam.InverseGamma`, a user's own)
gives

* ``dim`` — the dimension of the variable;
* ``mean()`` ``(d,)`` and ``cov()`` ``(d, d)`` — its first two moments (NaN where a
  moment does not exist, as an inverse-Gamma's variance for ``α ≤ 2``);
* ``estimate()`` ``(d,)`` — the point estimate a readout reports (the mean, except for a
  noise belief: its plug-in variance ``β/α``);
* ``log_mass`` — the log of its total mass: 0 for a density, the log expected number of
  targets for an intensity, the log evidence so far for unnormalised particles.

A *batched belief* (a plate's variable, one row per replica: :class:`~pgm.core.batched.
BatchedParticles`, :class:`~pgm.core.batched.BatchedGaussian`, ...) gives the same with a
leading replica axis (``mean()`` ``(K, d)``, ``cov()`` ``(K, d, d)``, ``log_mass``
``(K,)``) and the replica axis itself: ``K``, ``row(k)``, ``rows()``, ``stack(rows)``,
``select(indices)``, ``concat(other)`` and the class attribute ``row_type`` (the
belief of one replica). Births and deaths of a plate are ``concat`` and ``select``.

Both are :class:`typing.Protocol` classes checked at run time (``isinstance(b, Belief)``
tests that the names exist); ``tests/pgm/core/test_protocol.py`` holds every built-in
belief to them, values included.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["Belief", "BatchedBelief"]


@runtime_checkable
class Belief(Protocol):
    """One variable's belief (see the module docstring)."""

    @property
    def dim(self) -> int: ...

    @property
    def log_mass(self) -> Any: ...

    def mean(self) -> np.ndarray: ...

    def cov(self) -> np.ndarray: ...

    def estimate(self) -> np.ndarray: ...


@runtime_checkable
class BatchedBelief(Belief, Protocol):
    """A plate variable's belief, one row per replica (see the module docstring)."""

    row_type: Any

    @property
    def K(self) -> int: ...  # noqa: N802 - the plate's size is called K

    def row(self, k: int) -> Any: ...

    def rows(self) -> list[Any]: ...

    @classmethod
    def stack(cls, rows: Sequence[Any]) -> Any: ...

    def select(self, indices: Sequence[int] | np.ndarray) -> Any: ...

    def concat(self, other: Any) -> Any: ...
