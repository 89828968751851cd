"""Random generators by name: every consumer of randomness gets its own stream of the run's seed.

A stream depends on the seed and the consumer's stable name only (``"start_jitter"``,
``"planner/3"``, ``"range_noise"`` ...), never on which other consumers exist or in which order
they were built: turning a sensor on does not change any planner's draws.
"""

from __future__ import annotations

import hashlib

import numpy as np


def stream_key(name: str) -> tuple[int, int]:
    """Two 32-bit words that identify ``name`` (a stable hash, the same on every platform and run)."""
    digest = hashlib.blake2b(name.encode("utf-8"), digest_size=8).digest()
    return int.from_bytes(digest[:4], "little"), int.from_bytes(digest[4:], "little")


def named_rng(seed: int, name: str) -> np.random.Generator:
    """The generator of consumer ``name`` in a run seeded with ``seed`` (a non-negative integer)."""
    return np.random.default_rng(np.random.SeedSequence(entropy=int(seed), spawn_key=stream_key(name)))
