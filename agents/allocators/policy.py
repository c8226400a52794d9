"""A learned allocator: a linear score over the robot's K nearest frontier targets, read from a weights file.

The choice a reinforcement-learning policy makes in ``fleet_emu.rl`` (pick one of the robot's K best frontier
targets, as Explore-Bench and MAexp do) is made here from the same features, computed from the same
:class:`Problem`, so a policy trained in the memory engine runs unchanged in every robot process. The features
of a candidate cluster *j* (:data:`FEATURES`), all from what the robot knows:

- ``distance``: its wavefront cost from the robot, in units of :data:`DIST_SCALE` cells;
- ``size``: its frontier cells, in units of :data:`SIZE_SCALE`;
- ``closer``: how many teammates the robot believes are closer to it (their last known cells' costs);
- ``age``: the mean age of those beliefs (ticks since each closer teammate was heard), in units of
  :data:`AGE_SCALE` ticks (0 when none is closer);
- ``previous``: 1 when its target is the robot's previous decision's.

The candidates are the reachable clusters in order of ``distance`` (ties by cluster index), the first K. The
policy scores each ``w @ features`` and goes to the best (the first on a tie); without a file (``path=""``) the
weights are :data:`DEFAULT_WEIGHTS`, -1 on distance: the nearest frontier, exactly ``nearest``'s choice. The
scales are chosen once, so that each feature is of order one on the built-in maps.

A policy file is untrusted input, read once by the launcher (:func:`pin_policy`): a regular file of bounded
size whose zip members are checked before they are decompressed, with finite, bounded weights. The launcher
adds its sha256 to the allocator's parameters (``sha256``), so ``result.json`` records it and every robot,
which reads the file again in its own process, refuses a file that is no longer the one the run read.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import re
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.files import read_regular, write_atomic
from fleet_emu.core.messages import RadioMsg

FEATURES = ("distance", "size", "closer", "age", "previous")
DIST_SCALE = 32.0
SIZE_SCALE = 16.0
AGE_SCALE = 10.0
DEFAULT_K = 8
DEFAULT_WEIGHTS = (-1.0, 0.0, 0.0, 0.0, 0.0)


def candidates(problem: Problem, k: int) -> list[int]:
    """The robot's ``k`` nearest reachable clusters (indices into ``problem.clusters``), nearest first."""
    if not problem.clusters:
        return []
    mine = problem.costs[problem.index]
    order = sorted((d, j) for j, d in enumerate(mine) if np.isfinite(d))
    return [j for _, j in order[:k]]


def target_features(problem: Problem, cands: Sequence[int]) -> np.ndarray:
    """The :data:`FEATURES` of each candidate, a ``(len(cands), len(FEATURES))`` float32 array."""
    out = np.zeros((len(cands), len(FEATURES)), dtype=np.float32)
    if not cands:
        return out
    costs, me = problem.costs, problem.index
    robots = problem.robots
    ages = np.array([problem.tick - problem.heard.get(r, problem.tick) for r in robots], dtype=np.float64)
    for row, j in enumerate(cands):
        mine = costs[me, j]
        closer = [i for i in range(len(robots)) if i != me and costs[i, j] < mine]
        out[row] = (mine / DIST_SCALE, problem.clusters[j].size / SIZE_SCALE, len(closer),
                    float(ages[closer].mean()) / AGE_SCALE if closer else 0.0,
                    float(problem.clusters[j].target == problem.previous_target))
    return out


def choose(weights: np.ndarray, feats: np.ndarray) -> int | None:
    """The row of the best-scored candidate (the first on a tie), None without one."""
    return int(np.argmax(feats @ weights)) if len(feats) else None


#: A policy file's bounds: the file, each array once decompressed, K, and each weight's magnitude (a linear
#: score of features of order one to a few thousand stays finite in float64 far beyond that).
MAX_FILE_BYTES = 1 << 20
MAX_MEMBER_BYTES = 64 << 10
MAX_K = 256
MAX_WEIGHT = 1e6
_MEMBERS = ("weights.npy", "k.npy", "features.npy")
_HEX = re.compile(r"[0-9a-f]{64}")


@dataclasses.dataclass(frozen=True)
class PolicyFile:
    """A policy file read and checked: its weights, K and the sha256 of its bytes."""

    weights: np.ndarray
    k: int
    sha256: str


_read: dict[tuple[str, str], PolicyFile] = {}


def read_policy(path: str, sha256: str = "") -> PolicyFile:
    """The policy file at ``path`` (``.npz`` with ``weights``, ``k`` and ``features``), read once: a regular file
    of at most :data:`MAX_FILE_BYTES`, its members' sizes checked before and while they are decompressed, its
    weights finite and within :data:`MAX_WEIGHT`. With ``sha256`` (the digest the launcher read) a file whose
    bytes are not those is refused: every robot runs the weights the run recorded. A ConfigError of one line."""
    key = (path, sha256)
    if sha256 and key in _read:
        return _read[key]
    try:
        data = read_regular(path, MAX_FILE_BYTES)
    except FileNotFoundError:
        raise ConfigError(f"cannot read the policy file {path!r}: no such file") from None
    except OSError as exc:
        raise ConfigError(f"cannot read the policy file {path!r}: {exc.strerror or exc}") from None
    digest = hashlib.sha256(data).hexdigest()
    if sha256 and digest != sha256:
        raise ConfigError(f"the policy file {path!r} changed since the run read it (sha256 {digest[:12]}..., the "
                          f"run's {sha256[:12]}...): its robots run only the weights the run recorded")
    weights, k = parse_policy(data, path)
    _read[(path, digest)] = policy = PolicyFile(weights, k, digest)
    return policy


def parse_policy(data: bytes, path: str = "") -> tuple[np.ndarray, int]:
    """The weights and K of a policy file's bytes; a ConfigError of one line when it is not one (a zip of
    exactly :data:`_MEMBERS`, each at most :data:`MAX_MEMBER_BYTES` decompressed, no pickles), was saved for
    other features, or holds weights that are not finite or over :data:`MAX_WEIGHT`."""
    where = f"the policy file {path!r}"
    arrays = _members(data, where)
    try:
        weights = np.asarray(arrays["weights"], dtype=np.float64)
        k_arr = arrays["k"]
        names = tuple(str(n) for n in arrays["features"].reshape(-1))
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"cannot read {where}: {exc}") from None
    if names != FEATURES or weights.shape != (len(FEATURES),) or k_arr.shape != () or k_arr.dtype.kind not in "iu":
        raise ConfigError(f"{where} is not a linear policy over {', '.join(FEATURES)}")
    k = int(k_arr)
    if not 1 <= k <= MAX_K:
        raise ConfigError(f"{where}: k must be from 1 to {MAX_K} (got {k})")
    if not (np.isfinite(weights).all() and (np.abs(weights) <= MAX_WEIGHT).all()):
        raise ConfigError(f"{where}: every weight must be a finite number within [-{MAX_WEIGHT:g}, {MAX_WEIGHT:g}] "
                          f"(got {', '.join(f'{w:g}' for w in weights)})")
    return weights, k


def _members(data: bytes, where: str) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz``'s bytes, each member's size checked in the zip's directory before it is
    decompressed and its decompression stopped past the bound (a header may lie)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            infos = z.infolist()
            if sorted(i.filename for i in infos) != sorted(_MEMBERS):
                raise ConfigError(f"{where} is not a policy file (an .npz of {', '.join(_MEMBERS)}; it holds "
                                  f"{', '.join(i.filename for i in infos[:5]) or 'nothing'})")
            out = {}
            for info in infos:
                if info.file_size > MAX_MEMBER_BYTES:
                    raise ConfigError(f"{where}: {info.filename} would be {info.file_size} bytes decompressed "
                                      f"(at most {MAX_MEMBER_BYTES})")
                with z.open(info) as f:
                    raw = f.read(MAX_MEMBER_BYTES + 1)
                if len(raw) > MAX_MEMBER_BYTES:
                    raise ConfigError(f"{where}: {info.filename} is over {MAX_MEMBER_BYTES} bytes decompressed")
                out[info.filename[:-4]] = np.lib.format.read_array(io.BytesIO(raw), allow_pickle=False)
            return out
    except ConfigError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError, NotImplementedError) as exc:
        raise ConfigError(f"cannot read {where}: not an .npz policy file ({exc})") from None


def load_policy(path: str) -> tuple[np.ndarray, int]:
    """The weights and K of a policy file (:func:`read_policy`)."""
    policy = read_policy(path)
    return policy.weights, policy.k


def pin_policy(allocator: dict[str, Any]) -> dict[str, Any]:
    """``allocator`` (a scenario's table) with the sha256 of its policy file, read now (by the launcher, before
    any robot starts): the robots verify it (:func:`read_policy`) and ``result.json`` records it. Any other
    allocator's table is returned as it is."""
    if allocator.get("type") != "policy" or not allocator.get("path"):
        return allocator
    given = allocator.get("sha256", "")
    policy = read_policy(str(allocator["path"]), given if isinstance(given, str) else "")
    return allocator | {"sha256": policy.sha256}


def save_policy(path: str | Path, weights: np.ndarray, k: int = DEFAULT_K) -> None:
    """Write a policy file :func:`load_policy` reads (``.npz`` added to a name without it, as numpy does), whole
    (:func:`~fleet_emu.core.files.write_atomic`)."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, weights=np.asarray(weights, dtype=np.float64), k=np.int64(k), features=np.array(FEATURES))

    write_atomic(path, write)


class Policy(Allocator, plugin_name="policy"):
    """A learned linear policy over the K nearest frontier targets (fleet_emu.rl trains one)."""

    DESCRIPTION = "a learned linear policy over the robot's K nearest frontier targets, from a weights file (path)"
    parameters = {"path": Param(""), "sha256": Param("")}
    path: str
    sha256: str

    def __init__(self, **params: object) -> None:
        super().__init__(**params)
        if self.sha256 and not _HEX.fullmatch(self.sha256):
            raise ConfigError(f"allocator policy: sha256 must be 64 hexadecimal digits (got {self.sha256!r})")
        if self.path:
            policy = read_policy(str(self.path), self.sha256)
            self.weights, self.k = policy.weights, policy.k
        else:
            self.weights, self.k = np.array(DEFAULT_WEIGHTS), DEFAULT_K

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        cands = candidates(problem, self.k)
        row = choose(self.weights, target_features(problem, cands))
        return Allocation.none() if row is None else Allocation.assigned(problem, cands[row])
