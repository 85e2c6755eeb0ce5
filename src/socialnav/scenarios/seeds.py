"""Episode seeds: an episode is named by (split, index) and its seed is ``SPLIT_BASES[split] + index``.

CrowdNav's scheme (docs/internals.md, "Episode seeds and randomness"): validation seeds 0..999,
test seeds 1000..1999, training seeds from 2000 on, so the splits never share an episode.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["SPLIT_BASES", "SPLIT_SIZE", "as_indices", "episode_seeds"]

SPLIT_BASES: dict[str, int] = {"val": 0, "test": 1000, "train": 2000}
"""First seed of each split (CrowdNav's scheme: val 0 + i, test 1000 + i, train from 2000 on)."""
#: Largest number of val / test episodes per scenario that keeps the splits' seeds disjoint.
SPLIT_SIZE = 1000


def episode_seeds(split: str, indices: np.ndarray | Sequence[int] | int) -> np.ndarray:
    """Seeds of the episodes ``indices`` of a split: ``SPLIT_BASES[split] + index``.

    Validation and test indices must lie in [0, 1000) so the splits never share a seed; training
    indices are unbounded (seeds 2000 and up).

    Args:
        split: "val", "test" or "train".
        indices: Episode indices within the split [(B,) int, or a scalar].

    Returns:
        Seeds [(B,) int64].

    Raises:
        ValueError: Unknown split, or an index outside the split's range.
    """
    if split not in SPLIT_BASES:
        valid = ", ".join(repr(s) for s in SPLIT_BASES)
        raise ValueError(f"unknown split {split!r}; valid splits: {valid}")
    idx = as_indices(indices, copy=False)  # only read here (a world's refill calls this every step)
    if idx.size and idx.min() < 0:
        raise ValueError(f"episode indices must be >= 0, got {int(idx.min())}")
    if split != "train" and idx.size and idx.max() >= SPLIT_SIZE:
        raise ValueError(
            f"split {split!r} holds indices 0..{SPLIT_SIZE - 1} (seeds would overlap the next "
            f"split); got index {int(idx.max())}"
        )
    return SPLIT_BASES[split] + idx


def as_indices(indices: np.ndarray | Sequence[int] | int, copy: bool = True) -> np.ndarray:
    """Episode indices checked as a 1-D int64 array.

    Args:
        indices: Indices [(B,) int, or a scalar].
        copy: False returns an int64 input itself (for callers that only read it).

    Returns:
        The indices [(B,) int64].

    Raises:
        ValueError: More than one dimension.
        TypeError: Not integers.
    """
    if type(indices) is np.ndarray and indices.dtype == np.int64 and indices.ndim == 1:
        return indices.copy() if copy else indices  # the common case (a world's refill, every step)
    arr = np.atleast_1d(np.asarray(indices))
    if arr.ndim != 1:
        raise ValueError(f"indices must be 1-D, got shape {arr.shape}")
    if arr.size == 0:
        return arr.astype(np.int64, copy=copy)
    if not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"indices must be integers, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=copy)

