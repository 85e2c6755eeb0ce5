"""Counter-based random numbers, vectorised over episodes.

`EpisodeRandom` gives every episode of a batch its own random stream without any mutable
generator state: a draw is a pure function of (episode seed, salt, key, element), where the key
is a tuple of integers chosen by the caller (e.g. ``(STREAM_START, human j, attempt a)``). Row b
of every draw therefore depends only on ``seeds[b]``, the salt (the scenario's name) and the key,
never on the other rows, the batch size or the order of the calls. This is what makes an episode
replayable alone and lets scenario generation be vectorised over the batch.

The hash is the splitmix64 finaliser (Steele, Lea & Flood, "Fast splittable pseudorandom number
generators", OOPSLA 2014; the constants are those of Java's SplittableRandom) chained over the
64-bit words of the address. Each step ``h <- fmix64((h ^ word) + GOLDEN)`` is a bijection of the
word for a fixed h, so distinct addresses collide only by chance (about 2**-64 per pair).
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence

import numpy as np

__all__ = ["EpisodeRandom", "salt_hash"]

_MASK = (1 << 64) - 1
_GOLDEN = 0x9E3779B97F4A7C15
_M1 = 0xBF58476D1CE4E5B9
_M2 = 0x94D049BB133111EB

_U_GOLDEN = np.uint64(_GOLDEN)
_U_M1 = np.uint64(_M1)
_U_M2 = np.uint64(_M2)
_U30 = np.uint64(30)
_U27 = np.uint64(27)
_U31 = np.uint64(31)
_U11 = np.uint64(11)
_TWO_M53 = 2.0**-53


def _fmix_int(z: int) -> int:
    """Splitmix64 finaliser on a Python int (scalar path, used for the key prefix)."""
    z &= _MASK
    z = ((z ^ (z >> 30)) * _M1) & _MASK
    z = ((z ^ (z >> 27)) * _M2) & _MASK
    return z ^ (z >> 31)


def _fmix_array(z: np.ndarray) -> np.ndarray:
    """Splitmix64 finaliser on a uint64 array (wrap-around multiplication is intended)."""
    z = z ^ (z >> _U30)
    z *= _U_M1
    z ^= z >> _U27
    z *= _U_M2
    z ^= z >> _U31
    return z


def _chain_int(h: int, word: int) -> int:
    """Absorb one 64-bit word into the running hash h (scalar)."""
    return _fmix_int(((h ^ (word & _MASK)) + _GOLDEN) & _MASK)


def salt_hash(salt: str) -> int:
    """Stable 64-bit hash of a salt string.

    Python's built-in `hash` of a str is randomised per process, so it cannot be used for
    reproducible streams; CRC-32 of the UTF-8 bytes plus the length, mixed to 64 bits, is stable
    across processes, platforms and Python versions.

    Args:
        salt: Any string, usually the scenario's registered name.

    Returns:
        An integer in [0, 2**64).
    """
    data = salt.encode("utf-8")
    return _chain_int(_chain_int(0, zlib.crc32(data)), len(data))


class EpisodeRandom:
    """Counter-based uniform random numbers for a batch of episodes.

    Every method takes a key, a tuple of Python ints naming the draw; calling twice with the same
    key returns the same numbers. Rows are independent: ``EpisodeRandom(seeds[idx], salt)``
    yields exactly the rows ``idx`` of ``EpisodeRandom(seeds, salt)``.

    Args:
        seeds: Episode seeds [(B,) int64]. Negative values are allowed (taken modulo 2**64).
        salt: Names the stream, usually the scenario's registered name, so that two scenarios
            given the same seed draw unrelated numbers.

    Example:
        >>> rng = EpisodeRandom(np.array([1000, 1001]), "circle_crossing")
        >>> rng.uniform((0, 3, 0), 0.0, 2 * np.pi).shape
        (2,)
    """

    __slots__ = ("_seed_hash", "salt", "seeds")

    def __init__(self, seeds: np.ndarray | Sequence[int], salt: str) -> None:
        """Hash the salt and each seed once; see the class docstring for the arguments."""
        seeds_arr = np.asarray(seeds)
        if seeds_arr.ndim != 1:
            raise ValueError(f"seeds must be a 1-D array, got shape {seeds_arr.shape}")
        if seeds_arr.size and not np.issubdtype(seeds_arr.dtype, np.integer):
            raise TypeError(f"seeds must be integers, got dtype {seeds_arr.dtype}")
        self.seeds = seeds_arr.astype(np.int64, copy=False)
        self.salt = str(salt)
        with np.errstate(over="ignore"):
            # Per-episode prefix: the salt and the seed are absorbed once; every draw then only
            # absorbs its own key (scalar work) and element counter (one array finaliser).
            h0 = np.uint64(_fmix_int(salt_hash(self.salt) + _GOLDEN))
            self._seed_hash = _fmix_array((self.seeds.view(np.uint64) ^ h0) + _U_GOLDEN)

    def __len__(self) -> int:
        """Number of episodes B."""
        return int(self.seeds.shape[0])

    def __repr__(self) -> str:
        """Batch size and salt (the seeds may be many)."""
        return f"EpisodeRandom(B={len(self)}, salt={self.salt!r})"

    def take(self, idx: np.ndarray) -> EpisodeRandom:
        """Restrict to a subset of episodes; the rows keep their numbers exactly.

        Args:
            idx: Integer indices or boolean mask into the batch [(B',) or (B,)].

        Returns:
            An `EpisodeRandom` over ``seeds[idx]``.
        """
        sub = EpisodeRandom.__new__(EpisodeRandom)
        sub.seeds = self.seeds[idx]
        sub.salt = self.salt
        sub._seed_hash = self._seed_hash[idx]
        return sub

    def bits(self, key: tuple[int, ...], size: int | tuple[int, ...] = ()) -> np.ndarray:
        """Raw 64-bit hashes addressed by (seed, salt, key, element).

        Args:
            key: Tuple of ints naming the draw (any sign, taken modulo 2**64).
            size: Extra trailing shape per episode.

        Returns:
            uint64 array [(B, *size)].
        """
        size = (int(size),) if isinstance(size, (int, np.integer)) else tuple(map(int, size))
        if not isinstance(key, tuple):
            raise TypeError(f"key must be a tuple of ints, got {type(key).__name__}")
        kh = _chain_int(0x5EED, len(key))
        for word in key:
            kh = _chain_int(kh, int(word))
        n_elem = int(np.prod(size, dtype=np.int64))
        # The element counter is absorbed into the (scalar) key hash per element, so the only
        # per-episode array work is one XOR and one finaliser over B * n_elem words.
        elem = np.array([_chain_int(kh, e) for e in range(n_elem)], dtype=np.uint64)
        with np.errstate(over="ignore"):
            h = _fmix_array((self._seed_hash[:, None] ^ elem[None, :]) + _U_GOLDEN)
        return h.reshape((len(self), *size))

    def random(self, key: tuple[int, ...], size: int | tuple[int, ...] = ()) -> np.ndarray:
        """Uniform floats in [0, 1) with 53 random bits.

        Args:
            key: Tuple of ints naming the draw.
            size: Extra trailing shape per episode.

        Returns:
            float64 array [(B, *size)].
        """
        return (self.bits(key, size) >> _U11).astype(np.float64) * _TWO_M53

    def uniform(
        self,
        key: tuple[int, ...],
        low: float = 0.0,
        high: float = 1.0,
        size: int | tuple[int, ...] = (),
    ) -> np.ndarray:
        """Uniform floats in [low, high).

        Args:
            key: Tuple of ints naming the draw.
            low: Lower bound (scalar or broadcastable to (B, *size)).
            high: Upper bound (scalar or broadcastable to (B, *size)).
            size: Extra trailing shape per episode.

        Returns:
            float64 array [(B, *size)].
        """
        return low + (high - low) * self.random(key, size)

    def integers(
        self, key: tuple[int, ...], low: int, high: int, size: int | tuple[int, ...] = ()
    ) -> np.ndarray:
        """Uniform integers in [low, high).

        Args:
            key: Tuple of ints naming the draw.
            low: Smallest value.
            high: One past the largest value; ``high - low`` must be in [1, 2**53].
            size: Extra trailing shape per episode.

        Returns:
            int64 array [(B, *size)].
        """
        n = int(high) - int(low)
        if not 1 <= n <= 2**53:
            raise ValueError(f"integers needs 1 <= high - low <= 2**53, got low={low}, high={high}")
        # floor(u * n) with u on the 2**-53 grid: exact for n <= 2**53, bias <= n / 2**53.
        return int(low) + np.floor(self.random(key, size) * n).astype(np.int64)

    def choice_sign(self, key: tuple[int, ...], size: int | tuple[int, ...] = ()) -> np.ndarray:
        """Random signs, −1 or +1 with probability 1/2 each.

        Follows CrowdSim's ``sign = -1 if random() > 0.5 else 1``.

        Args:
            key: Tuple of ints naming the draw.
            size: Extra trailing shape per episode.

        Returns:
            float64 array of ±1.0 [(B, *size)].
        """
        return np.where(self.random(key, size) > 0.5, -1.0, 1.0)
