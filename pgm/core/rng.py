"""Random-number generators at user boundaries (scikit-learn's ``check_random_state``).

Inside the toolkit every stochastic function takes ``rng: numpy.random.Generator`` as
its first argument; seeds are accepted only at user-facing boundaries and converted here.
"""

from __future__ import annotations

import numpy as np

__all__ = ["as_generator"]


def as_generator(seed: int | np.random.Generator | None) -> np.random.Generator:
    """Return a ``numpy.random.Generator`` from a seed, a generator or ``None``."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        return np.random.default_rng()
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        if seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed}")
        return np.random.default_rng(int(seed))
    raise ValueError(f"seed must be an int, a numpy Generator or None, got {type(seed).__name__}")
