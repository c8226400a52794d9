"""One seed, passed down: every process derives its generator from the run seed and its own name."""

from __future__ import annotations

import hashlib

import numpy as np


def derive_seed(seed: int, *names: str) -> int:
    """A stable 63-bit seed for ``names`` under ``seed`` (independent of PYTHONHASHSEED)."""
    h = hashlib.sha256(repr((int(seed), *names)).encode()).digest()
    return int.from_bytes(h[:8], "little") >> 1


def generator(seed: int, *names: str) -> np.random.Generator:
    """The seeded generator of one component (``generator(seed, "netem")``, ``generator(seed, "r3")``)."""
    return np.random.default_rng(derive_seed(seed, *names))
