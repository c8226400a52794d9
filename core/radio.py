"""The radio: its one parameter type, and the signal model (docs/guides/radio.md; Benavides et al.
2016, eq. 4, after RADAR), shared by netem (on the true map) and the connectivity allocator (on a belief).

    P_ij = -10 * PL * log10(d_ij / c) - min(nW_ij, C) * WAF

``d_ij`` is the Euclidean distance in metres between the two cells, ``c`` the nominal range (P = 0 dB in
free space), ``nW_ij`` the walls the straight segment crosses on the map (maximal runs of occupied cells),
``C`` the cap on counted walls and ``WAF`` the attenuation per wall. A link exists when ``P_ij >= threshold``.
Pure functions of arrays: netem uses them on the true map, agents on their belief (Benavides eq. 8).

Radio models (``RadioConfig.comm``), loss orthogonal to range: ``wall`` (eq. 4 decides the link), ``disk``
(linked within ``comm_range`` metres, straight-line), ``full`` (every pair linked), and ``ideal`` (``full``
with no loss, kept for comparison). The loss probability applies on every model but ``ideal``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from fleet_emu.core.grid import Cell

COMM_MODELS = ("wall", "disk", "full", "ideal")


@dataclasses.dataclass(frozen=True)
class RadioConfig:
    """The radio of a scenario (``[radio]``), of netem and of the connectivity allocator's prediction:
    ``comm`` the model (see the module docstring), ``loss`` per message and receiver on an existing link,
    ``comm_range`` c in metres, ``path_loss`` PL, ``waf`` dB per wall, ``max_walls`` C, ``threshold`` dB for a
    link, ``latency`` ticks from the last byte on the air to delivery; ``bandwidth`` kbit/s of one shared medium
    (0: unlimited, every message is on the air in its tick), ``queue_bytes`` each sender's queue (drop-tail),
    ``jitter`` the most ticks (seeded, uniform) added to ``latency`` per message (netem/medium.py)."""

    comm: str = "wall"
    loss: float = 0.1
    comm_range: float = 10.0
    path_loss: float = 2.0
    waf: float = 3.1
    max_walls: int = 4
    threshold: float = 0.0
    latency: int = 1
    bandwidth: float = 0.0
    queue_bytes: int = 1_000_000
    jitter: int = 0

    @property
    def applied_loss(self) -> float:
        """The loss probability the channel applies: none on the ideal radio."""
        return 0.0 if self.comm == "ideal" else self.loss

    @property
    def limited(self) -> bool:
        """Whether the radio charges airtime (a bandwidth is set): senders queue, media are shared."""
        return self.bandwidth > 0

    def capacity(self, tick_s: float) -> float:
        """Bytes one medium carries in a tick of ``tick_s`` seconds: ``bandwidth * 1000 / 8 * tick_s``."""
        return self.bandwidth * 1000.0 / 8.0 * tick_s

    @property
    def sure_range(self) -> float:
        """The distance in metres within which two endpoints are linked whatever lies between them: ``disk``,
        its range; ``wall``, eq. 4 solved for ``P = threshold`` with ``max_walls`` walls (the most it counts);
        ``full`` and ``ideal`` (or a path loss of 0), infinite."""
        if self.comm == "disk":
            return self.comm_range
        if self.comm == "wall" and self.path_loss > 0:
            return self.comm_range * 10 ** (-(self.threshold + self.max_walls * self.waf) / (10 * self.path_loss))
        return math.inf


def radio_label(comm: str, loss: float) -> str:
    """The radio model and the loss the channel actually applies (none on ``ideal``, whatever was asked), as
    ``fleet run``'s summary and ``fleet report``'s tables show it."""
    applied = RadioConfig(comm=comm, loss=loss).applied_loss
    return f"{comm}, no loss" if applied == 0 else f"{comm}, loss {applied:g}"


def signal_db(distance_m: float, walls: int, p: RadioConfig) -> float:
    """Benavides eq. 4 for one pair; ``distance_m`` is clamped to a millimetre (same-cell pairs)."""
    d = max(distance_m, 1e-3)
    return -10.0 * p.path_loss * math.log10(d / p.comm_range) - min(walls, p.max_walls) * p.waf


def link_matrix(occupied: np.ndarray, cells: Sequence[Cell], cell_size: float,
                p: RadioConfig) -> tuple[np.ndarray, np.ndarray]:
    """Signal strength (dB, symmetric, ``inf`` on the diagonal) and links (bool, no self-links) between
    robots at ``cells`` on a map whose walls are ``occupied``. The strength is eq. 4's on every model; the
    link follows the model: eq. 4's threshold (``wall``), distance within ``comm_range`` (``disk``), or every
    pair (``full``, ``ideal``)."""
    from fleet_emu.core.kernels import count_walls  # numba: imported on first use, not with the CLI

    n = len(cells)
    strength = np.full((n, n), np.inf)
    for i in range(n):
        for j in range(i + 1, n):
            (r0, c0), (r1, c1) = cells[i], cells[j]
            d = math.hypot(r1 - r0, c1 - c0) * cell_size
            walls = int(count_walls(occupied, r0, c0, r1, c1))
            strength[i, j] = strength[j, i] = signal_db(d, walls, p)
    if p.comm == "wall":
        link = strength >= p.threshold
    elif p.comm == "disk":
        rc = np.array(cells, dtype=float).reshape(n, 2)
        gap = np.hypot(rc[:, None, 0] - rc[None, :, 0], rc[:, None, 1] - rc[None, :, 1]) * cell_size
        link = gap <= p.comm_range
    else:
        link = np.ones((n, n), dtype=bool)
    np.fill_diagonal(link, False)
    return strength, link


def connected(link: np.ndarray) -> bool:
    """Whether the undirected link graph is connected (one robot, or none, counts as connected)."""
    n = len(link)
    if n <= 1:
        return True
    seen = np.zeros(n, dtype=bool)
    seen[0] = True
    frontier = [0]
    while frontier:
        i = frontier.pop()
        for j in np.flatnonzero(link[i] & ~seen):
            seen[j] = True
            frontier.append(int(j))
    return bool(seen.all())
