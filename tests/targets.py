"""Shuffled targets, as the permutation control draws them, for the tests of its shortcuts (PLS and the law)."""
from __future__ import annotations

import numpy as np


def shuffled_targets(y: np.ndarray, groups: np.ndarray, n_targets: int, seed: int) -> np.ndarray:
    """The real target and shufflings of it across groups (every member of a group keeps one shared value)."""
    names, first, codes = np.unique(groups, return_index=True, return_inverse=True)
    values = y[first]
    rng = np.random.default_rng(seed)
    return np.column_stack([y] + [rng.permutation(values)[codes] for _ in range(n_targets - 1)])
