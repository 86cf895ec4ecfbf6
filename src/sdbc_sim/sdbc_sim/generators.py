"""The trials' random generators, ``numpy.random.default_rng(seed)`` for a whole
batch of seeds at once.

``default_rng(seed)`` is ``Generator(PCG64(SeedSequence(seed)))``: the seed
sequence hashes the seed's 32-bit words into a pool of four and derives PCG64's
128-bit state and increment from it. numpy does that one seed at a time, about
11 us each, which was more than a resource-sharing trial's whole start. Here the
same hashing runs over every seed as whole uint32 arrays (the operations of
numpy's ``SeedSequence``, mod 2^32; their multipliers do not depend on the
seed), and each generator is handed its words through :class:`_SeedWords`. The
generators are numpy's own objects with numpy's own state: the tests compare
every draw, the state and the seed sequence's fields with ``default_rng``'s.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from numpy.random import PCG64, Generator, SeedSequence
from numpy.random.bit_generator import ISpawnableSeedSequence

_POOL_SIZE = 4
_INIT_A = 0x43B0D7E5
_MULT_A = 0x931E8875
_INIT_B = 0x8B51F9DD
_MULT_B = 0x58F38DED
_MIX_MULT_L = 0xCA01F9DD
_MIX_MULT_R = 0x4973F715
_XSHIFT = 16
_MASK32 = 0xFFFFFFFF
_STATE_WORDS = 8
"""PCG64 asks for four 64-bit words: eight 32-bit ones, little end first."""


def _hash_constants(start: int, multiplier: int, count: int) -> list[tuple[int, int]]:
    """The (before, after) multiplier of each of ``count`` hashes: it changes
    with every hash the same way whatever is hashed."""
    out = []
    h = start
    for _ in range(count):
        after = (h * multiplier) & _MASK32
        out.append((h, after))
        h = after
    return out


# The pool's first four hashes, then one per ordered pair of its words.
_MIX_HASHES = _hash_constants(_INIT_A, _MULT_A, _POOL_SIZE * _POOL_SIZE)
_STATE_HASHES = _hash_constants(_INIT_B, _MULT_B, _STATE_WORDS)


Words = npt.NDArray[np.uint32]


def _hashmix(value: Words, constants: tuple[int, int]) -> Words:
    before, after = constants
    mixed: Words = np.multiply(value ^ np.uint32(before), np.uint32(after))
    return mixed ^ (mixed >> np.uint32(_XSHIFT))


def _mix(x: Words, y: Words) -> Words:
    result: Words = np.subtract(
        np.multiply(np.uint32(_MIX_MULT_L), x), np.multiply(np.uint32(_MIX_MULT_R), y)
    )
    return result ^ (result >> np.uint32(_XSHIFT))


def _state_words(seeds: np.ndarray) -> np.ndarray:
    """(B, 4) uint64, what ``SeedSequence(seed).generate_state(4, np.uint64)``
    gives for each of ``seeds`` (B,), integers in [0, 2^64)."""
    seeds = seeds.astype(np.uint64)
    low = (seeds & np.uint64(_MASK32)).astype(np.uint32)
    high = (seeds >> np.uint64(32)).astype(np.uint32)
    # A seed below 2^32 is one word; the pool's missing words hash a zero.
    entropy = [low, np.where(seeds >> np.uint64(32) != 0, high, np.uint32(0))]
    entropy += [np.zeros_like(low)] * (_POOL_SIZE - len(entropy))
    hashes = iter(_MIX_HASHES)
    with np.errstate(over="ignore"):
        pool = [_hashmix(word, next(hashes)) for word in entropy]
        for src in range(_POOL_SIZE):
            for dst in range(_POOL_SIZE):
                if src != dst:
                    pool[dst] = _mix(pool[dst], _hashmix(pool[src], next(hashes)))
        state = np.empty((seeds.shape[0], _STATE_WORDS), dtype=np.uint32)
        for i, constants in enumerate(_STATE_HASHES):
            state[:, i] = _hashmix(pool[i % _POOL_SIZE], constants)
    return state.astype("<u4").view("<u8").astype(np.uint64)


class _SeedWords(ISpawnableSeedSequence):
    """The seed sequence of one trial's generator: its state words, computed in
    bulk, for PCG64's seeding; anything else (``entropy``, ``spawn``, the state
    in other sizes) from numpy's own ``SeedSequence(seed)``, built on first use
    and kept, so the generator's ``seed_seq`` behaves as ``default_rng``'s."""

    def __init__(self, seed: int, words: np.ndarray) -> None:
        self._seed = seed
        self._words = words
        self._sequence: SeedSequence | None = None

    def _numpys(self) -> SeedSequence:
        if self._sequence is None:
            self._sequence = SeedSequence(self._seed)
        return self._sequence

    def generate_state(self, n_words: int, dtype: Any = np.uint32) -> np.ndarray:
        if n_words == _STATE_WORDS // 2 and np.dtype(dtype) == np.uint64:
            return self._words.copy()
        return self._numpys().generate_state(n_words, dtype)

    def spawn(self, n_children: int) -> list[Any]:
        # numpy's children, as default_rng's seed sequence spawns them.
        return self._numpys().spawn(n_children)

    def __getattr__(self, name: str) -> Any:
        # entropy, spawn_key, pool, n_children_spawned, ...
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._numpys(), name)


def trial_generators(seeds: np.ndarray) -> list[Generator]:
    """``[numpy.random.default_rng(s) for s in seeds]`` for integer ``seeds``
    (B,) in [0, 2^64), built at a tenth of the cost per seed.

    Raises:
        ValueError: If a seed is negative or not below 2^64.
    """
    values = [int(s) for s in np.asarray(seeds).reshape(-1)]
    if any(not 0 <= s < 2**64 for s in values):
        raise ValueError("trial_generators: every seed must lie in [0, 2^64)")
    if not values:
        return []
    words = _state_words(np.array(values, dtype=np.uint64))
    return [
        Generator(PCG64(_SeedWords(s, w))) for s, w in zip(values, words, strict=True)
    ]
