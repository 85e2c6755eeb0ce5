"""The order in which an environment plays the episodes of its split.

An env's stream of positions 0, 1, 2, … maps to episode indices: ``reset(seed=s)`` plays episodes
``s·SEED_STRIDE, s·SEED_STRIDE+1, …`` of an endless split, or a permutation of a finite split drawn
from s (a new one each time round); ``reset(options={"index": k})`` plays k, k+1, … (see
:mod:`socialnav.envs.single`).
"""

from __future__ import annotations

import numpy as np

SEED_STRIDE = 10_000_000  # episodes between the streams of consecutive seeds of an endless split


class EpisodeOrder:
    """The episode index each position 0, 1, 2, … of an env's stream plays.

    Args:
        n_episodes: Size of a finite episode set (cycled through), or None for an endless split.
        seed: Seeded order (see the module docstring); seeds >= 2**32 are hashed into [0, 2**32).
        start: Contiguous order from this episode index instead.
    """

    def __init__(self, n_episodes: int | None, *, seed: int | None = None, start: int | None = None):
        if (seed is None) == (start is None):
            raise ValueError("EpisodeOrder needs exactly one of seed and start")
        self.n = n_episodes
        if start is not None:
            start = int(start)
            if start < 0 or (self.n is not None and start >= self.n):
                where = f"0..{self.n - 1}" if self.n is not None else ">= 0"
                raise ValueError(f"episode index must be in {where}, got {start}")
        if seed is not None:
            seed = int(seed)
            if seed < 0:
                raise ValueError(f"seed must be >= 0, got {seed}")
            if seed >= 2**32:
                seed = int(np.random.SeedSequence(seed).generate_state(1)[0])
        self.seed, self.start = seed, start
        self._perms: dict[int, np.ndarray] = {}

    def __call__(self, positions: np.ndarray) -> np.ndarray:
        """The episode indices (same shape) that stream positions ``positions`` play."""
        pos = np.asarray(positions, dtype=np.int64)
        if self.start is not None:
            out = self.start + pos
            return out if self.n is None else out % self.n
        seed, n = self.seed, self.n
        assert seed is not None  # the constructor sets exactly one of seed and start
        if n is None:
            return seed * SEED_STRIDE + pos
        out = np.empty_like(pos)
        cycles = pos // n
        for c in np.unique(cycles):
            rows = cycles == c
            out[rows] = self._permutation(int(c), seed, n)[pos[rows] % n]
        return out

    def _permutation(self, cycle: int, seed: int, n: int) -> np.ndarray:
        if cycle not in self._perms:
            if len(self._perms) > 8:
                self._perms.clear()
            self._perms[cycle] = np.random.default_rng([seed, cycle]).permutation(n)
        return self._perms[cycle]
