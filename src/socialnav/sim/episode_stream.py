"""Where a World's episodes come from: a scenario's episodes handed out in index order.

A finished episode's slot is refilled from the world's stream (auto-reset). The stream generates ahead
in chunks; since every episode depends only on its (scenario, split, index), chunking changes no result.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from socialnav.scenarios import EpisodeBatch, Scenario, episode_seeds
from socialnav.scenarios.seeds import SPLIT_SIZE


class EpisodeStream:
    """Hands out episodes (scenario, split, index) in index order: ``start, start+1, …``.

    Args:
        scenario: The scenario generator.
        split: "train", "val" or "test" (decides the seeds).
        start: First episode index (first position when ``index_map`` is given).
        count: Number of episodes, or None for all of them: an endless stream on the ``train`` split,
            the rest of the split's 1000 indices on ``val`` and ``test``, the rest of a finite
            scenario's episodes.
        index_map: Maps stream positions (int64 array) to episode indices, for streams that are
            not ``start, start+1, …`` (the Gymnasium envs' seeded and cycling orders). The map
            decides where such a stream ends: a finite scenario does not cap it.
    """

    #: Episodes generated per call: generation has a fixed cost per call, and a world refills only
    #: a few slots per step, so episodes are generated ahead in chunks (results do not change:
    #: each episode depends only on its own index).
    chunk_size = 1024

    def __init__(
        self,
        scenario: Scenario,
        split: str = "test",
        start: int = 0,
        count: int | None = None,
        index_map: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        """Opens the stream at ``start`` (arguments: see the class).

        Raises:
            ValueError: ``count`` or ``start`` is negative, ``split`` is not a split's name, the
                episodes would run past the split's 1000 indices (``val``, ``test``), or ``start`` lies
                past a finite scenario's last episode.
        """
        if count is not None and count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        if start < 0:
            raise ValueError(f"start must be >= 0, got {start}")
        episode_seeds(split, np.zeros(1, dtype=np.int64))  # validates the split name early
        self.scenario = scenario
        self.split = split
        self.next_index = start  # next index handed out
        self._generated = start  # next index to generate
        self.stop = None if count is None else start + count
        self.index_map = index_map
        if index_map is None and split != "train" and scenario.n_episodes is None:
            # the split's seeds end at its last index: said now, not after hundreds of episodes
            if self.stop is not None and self.stop > SPLIT_SIZE:
                raise ValueError(f"split {split!r} holds episode indices 0..{SPLIT_SIZE - 1}: start {start} "
                                 f"+ count {count} runs past them (use split='train' for more episodes)")
            self.stop = SPLIT_SIZE if self.stop is None else self.stop
        if scenario.n_episodes is not None and index_map is None:
            # A finite scenario (the single-human sweeps) ends the stream at its last episode.
            if start >= scenario.n_episodes and count != 0:
                raise ValueError(f"start {start} is past the scenario's last episode (it has "
                                 f"{scenario.n_episodes}: indices 0..{scenario.n_episodes - 1})")
            self.stop = scenario.n_episodes if self.stop is None else min(self.stop, scenario.n_episodes)
        self._buffer: EpisodeBatch | None = None
        self._buffer_pos = 0

    @property
    def remaining(self) -> int | None:
        """Episodes not handed out yet (None: an endless stream)."""
        return None if self.stop is None else self.stop - self.next_index

    @property
    def buffered(self) -> int:
        """Episodes generated ahead by :meth:`take` and not handed out yet."""
        return 0 if self._buffer is None else len(self._buffer) - self._buffer_pos

    def take_indices(self, k: int) -> np.ndarray | None:
        """The indices of the next ``min(k, remaining)`` episodes, without generating them.

        A world with a native generator generates them in place.

        Args:
            k: Episodes wanted.

        Returns:
            (n,) int64 episode indices, n = ``min(k, remaining)``, or None when exhausted.

        Raises:
            RuntimeError: :meth:`take` generated episodes ahead that were not handed out yet.
        """
        if self.buffered:
            raise RuntimeError("take_indices after take: hand out the buffered episodes with take first")
        if self.stop is not None:
            k = min(k, self.stop - self.next_index)
        if k <= 0:
            return None
        indices = np.arange(self.next_index, self.next_index + k, dtype=np.int64)
        if self.index_map is not None:
            indices = np.asarray(self.index_map(indices), dtype=np.int64)
        self.next_index += k
        self._generated = self.next_index
        return indices

    def take(self, k: int) -> EpisodeBatch | None:
        """The next ``min(k, remaining)`` episodes.

        Args:
            k: Episodes wanted.

        Returns:
            The episodes, or None when the stream is exhausted.
        """
        if self.stop is not None:
            k = min(k, self.stop - self.next_index)
        if k <= 0:
            return None
        buffer = self._buffer
        buffered = 0 if buffer is None else len(buffer) - self._buffer_pos
        if buffer is None or buffered < k:
            n = max(k - buffered, self.chunk_size)
            if self.stop is not None:
                n = min(n, self.stop - self._generated)
            indices = np.arange(self._generated, self._generated + n, dtype=np.int64)
            if self.index_map is not None:
                indices = np.asarray(self.index_map(indices), dtype=np.int64)
            fresh = self.scenario.generate(indices, episode_seeds(self.split, indices))
            self._generated += n
            if buffer is None or buffered == 0:
                buffer = fresh
            else:
                buffer = EpisodeBatch.concat([buffer.take(slice(self._buffer_pos, None)), fresh])
            self._buffer, self._buffer_pos = buffer, 0
        out = buffer.take(slice(self._buffer_pos, self._buffer_pos + k))
        self._buffer_pos += k
        self.next_index += k
        return out
