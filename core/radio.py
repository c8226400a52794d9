"""The radio: its one parameter type, and the signal model (docs/guides/radio.md; Benavides et al.
2016, eq. 4, after RADAR), shared by netem (on the true map) and the connectivity allocator (on a belief).

    P_ij = -10 * PL * log10(d_ij / c) - min(nW_ij, C) * WAF

``d_ij`` is the Euclidean distance in metres between the two cells, ``c`` the nominal range (P = 0 dB in
free space), ``nW_ij`` the walls the straight segment crosses on the map (maximal runs of occupied cells),
``C`` the cap on counted walls and ``WAF`` the attenuation per wall. A link exists when ``P_ij >= threshold``.
Pure functions of arrays: netem uses them on the true map, agents on their belief (Benavides eq. 8).

Radio models (``RadioConfig.comm``), loss orthogonal to range: ``wall`` (eq. 4 decides the link), ``disk``
(linked within ``comm_range`` metres, straight-line), ``full`` (every pair linked), and ``ideal`` (``full``
with no loss, kept for comparison). The loss probability applies on every model but ``ideal``. netem may add
correlated shadowing to the signal (``shadowing_db``, :mod:`fleet_emu.core.shadowing`); the connectivity
allocator's prediction never does.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from fleet_emu.core.fields import Setting, setting, settings

if TYPE_CHECKING:  # numpy is loaded by the functions that use it: a parser built from the settings needs none
    import numpy as np

    from fleet_emu.core.grid import Cell

COMM_MODELS = ("wall", "disk", "full", "ideal")


@dataclasses.dataclass(frozen=True)
class RadioConfig:
    """The radio of a scenario (``[radio]``), of netem and of the connectivity allocator's prediction.

    Every field is declared with :func:`~fleet_emu.core.fields.setting` (unit, range, flag, help): that one
    declaration makes it a ``fleet run`` flag (``--max-walls N``), a key of ``[radio]``, a key of a study's
    ``[grid]`` and ``[fleet]`` (flat, ``waf``, or in a ``radio`` table), a :meth:`Scenario.override` keyword,
    and checks it the same way in all of them (docs/guides/radio.md, "Every radio setting"). ``bandwidth``,
    ``queue_bytes`` and ``jitter`` make a radio that charges airtime (``netem/medium.py``)."""

    comm: str = setting("wall", choices=COMM_MODELS,
                        help="radio model: wall (eq. 4), disk (within --comm-range), full (all pairs), ideal "
                             "(full, no loss)")
    loss: float = setting(0.1, low=0.0, high=1.0, metavar="P",
                          help="per-message loss probability on an existing link")
    comm_range: float = setting(10.0, unit="m", low=0.0, high=1e6, low_open=True, metavar="M",
                                help="nominal range c in metres (P = 0 dB in free space)")
    path_loss: float = setting(2.0, low=0.0, high=100.0, metavar="PL", help="path-loss exponent PL of eq. 4")
    waf: float = setting(3.1, unit="dB", low=0.0, high=1000.0, metavar="DB",
                         help="wall attenuation factor: dB lost per wall crossed")
    max_walls: int = setting(4, low=0, high=10**6, metavar="N", help="most walls eq. 4 counts (C)")
    threshold: float = setting(0.0, unit="dB", low=-1000.0, high=1000.0, metavar="DB",
                               help="signal a wall-model link needs (P >= threshold)")
    latency: int = setting(1, unit="ticks", low=1, high=10**6, metavar="TICKS",
                           help="ticks from the last byte on the air to delivery")
    bandwidth: float = setting(0.0, unit="kbit/s", low=0.0, high=1e9, metavar="KBITPS", quiet=True,
                               help="capacity of one shared medium (robots that hear each other); 0: unlimited")
    queue_bytes: int = setting(1_000_000, unit="bytes", low=1, high=10**12, metavar="BYTES", quiet=True,
                               help="each sender's queue on a limited radio (drop-tail)")
    jitter: int = setting(0, unit="ticks", low=0, high=10**6, metavar="TICKS", quiet=True,
                          help="most ticks (seeded, uniform) added to the latency of each message")
    shadowing_db: float = setting(0.0, unit="dB", low=0.0, high=100.0, metavar="DB", quiet=True,
                                  help="standard deviation of the correlated shadowing added to every link's "
                                       "signal (core/shadowing.py); 0: off")
    shadowing_m: float = setting(1.0, unit="m", low=0.0, high=1e6, low_open=True, metavar="M", quiet=True,
                                 help="the shadowing's decorrelation distance (its correlation is 1/e there)")

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
        ``full`` and ``ideal`` (or a path loss of 0), infinite. Shadowing (``shadowing_db``) is not counted: it
        can take a link within this range away, as a robot that predicts from eq. 4 does not know."""
        if self.comm == "disk":
            return self.comm_range
        if self.comm == "wall" and self.path_loss > 0:
            return self.comm_range * 10 ** (-(self.threshold + self.max_walls * self.waf) / (10 * self.path_loss))
        return math.inf


@functools.cache
def radio_settings() -> tuple[Setting, ...]:
    """The declaration of every :class:`RadioConfig` field, in order (flags, tables, checks)."""
    return settings(RadioConfig)


def radio_label(comm: str, loss: float) -> str:
    """The radio model and the loss the channel actually applies (none on ``ideal``, whatever was asked), as
    ``fleet run``'s summary and ``fleet report``'s tables show it."""
    applied = RadioConfig(comm=comm, loss=loss).applied_loss
    return f"{comm}, no loss" if applied == 0 else f"{comm}, loss {applied:g}"


def bytes_per_robot_tick(bytes_sent: float, robots: int, ticks: int) -> float | None:
    """The run's bytes sent per robot and tick: ``result.json``'s ``radio.bytes_sent`` (every emission's
    encoded envelope once, docs/reference/result.md) over ``robots * ticks``; None for a run of no tick. The one
    rate the run's summary, ``metrics.json``, ``fleet report`` and the sweep tables show."""
    return bytes_sent / (robots * ticks) if robots > 0 and ticks > 0 else None


def bytes_line(bytes_sent: int, robots: int, ticks: int) -> str:
    """The bytes-sent row of the run's summary and of ``fleet report``: the total and the rate per robot-tick."""
    rate = bytes_per_robot_tick(bytes_sent, robots, ticks)
    return f"{bytes_sent / 1e6:.2f} MB, " + ("-" if rate is None else f"{rate:.0f}") + " per robot-tick"


def airtime_line(radio: Mapping[str, Any], scenario_radio: Mapping[str, Any]) -> str | None:
    """The airtime row of a radio that charges it (a bandwidth or a jitter, netem/medium.py), from
    ``result.json``'s ``radio`` and the scenario's ``[radio]``: the rate, the bytes on the air, the queues and the
    delay from hand-off to delivery; None for another radio."""
    if not (scenario_radio.get("bandwidth") or scenario_radio.get("jitter")):
        return None
    d = radio["delay_ticks"]
    rate = f"{scenario_radio['bandwidth']:g} kbit/s" if scenario_radio.get("bandwidth") else "unlimited"
    delay = "-" if d["mean"] is None else f"mean {d['mean']:.2f}, p95 {d['p95']}, max {d['max']}"
    return (f"{rate}: {radio['airtime_bytes'] / 1e6:.2f} MB on the air, {radio['dropped_queue']} dropped at a full "
            f"queue, largest queue {radio['queued_max_bytes'] / 1e3:.1f} kB; delay (ticks) {delay}")


def signal_db(distance_m: float, walls: int, p: RadioConfig) -> float:
    """Benavides eq. 4 for one pair; ``distance_m`` is clamped to a millimetre (same-cell pairs)."""
    d = max(distance_m, 1e-3)
    return -10.0 * p.path_loss * math.log10(d / p.comm_range) - min(walls, p.max_walls) * p.waf


def link_matrix(occupied: np.ndarray, cells: Sequence[Cell], cell_size: float,
                p: RadioConfig, shadow: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Signal strength (dB, symmetric, ``inf`` on the diagonal) and links (bool, no self-links) between
    robots at ``cells`` on a map whose walls are ``occupied``. The strength is eq. 4's on every model, plus
    ``shadow`` (dB per pair, symmetric: the correlated shadowing of :mod:`fleet_emu.core.shadowing`) when given;
    the link follows the model: that strength's threshold (``wall``), distance within ``comm_range``
    (``disk``), or every pair (``full``, ``ideal``)."""
    import numpy as np

    from fleet_emu.core.kernels import count_walls  # numba: imported on first use, not with the CLI

    n = len(cells)
    strength = np.full((n, n), np.inf)
    for i in range(n):
        for j in range(i + 1, n):
            (r0, c0), (r1, c1) = cells[i], cells[j]
            d = math.hypot(r1 - r0, c1 - c0) * cell_size
            walls = int(count_walls(occupied, r0, c0, r1, c1))
            strength[i, j] = strength[j, i] = signal_db(d, walls, p)
    if shadow is not None:
        strength += shadow
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
    import numpy as np

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
