"""Map consistency under loss: ticks to the target, how far the robots' beliefs disagree, and what the map
recovery (``agents/mapsync.py``) spends on the radio, on the memory engine.

    python -m benchmarks.map_sync [--map office] [--robots 3] [--allocator minpos] [--loss 0.3]
        [--comm full] [--seeds 8] [--start random|map|ROW,COL] [--json out.json]
    python -m benchmarks.map_sync --switch 0,0.1,0.3,0.5 [--robots 4] [--allocator trade] [--seeds 10]

Per seed: one run of the memory engine (``fe.Fleet``), its ``ticks`` (to the target coverage, or the last
tick when it was not reached: flagged ``*``), and two measures of map consistency from the robots' belief
grids, for every ordered pair (i, j) of robots: the cells j knows that i does not (``gap``), averaged over the
pairs, at the last tick (``gap_end``) and over every tick of the run (``gap_mean``). Cells learned in the last
tick are still in flight (one tick of latency), so the gap is never 0 while robots explore; a delta lost for
good stays in it. ``conflict`` counts cells both know with different values (0: sensing is exact). The radio
columns split the messages every robot emitted (each envelope once, as ``bytes_sent`` counts) by payload kind;
``rec.bytes`` is what map sync adds: the cells it sends again inside deltas (5 bytes a cell: an int32 index
and an int8 value), its whole-map fills (``mapfill``), and the bytes its fields add to beacons (the delta
count ``maps``, the requests ``want``) and to deltas (their number ``n``, the numbers sent again
``covers``); ``asks`` counts the beacons that carry a request, ``resent`` the deltas sent again. Run it with
the project's environment before and after a change (it uses only ``fe.Fleet``), and compare the JSON files
it writes.

``--switch LOSSES``: what the scenario's ``map_sync`` switch changes, one row per loss (the same seeds with map
sync on and off): the mean ticks to the target, their % change from the first loss listed (give 0 first), the
kilobytes every robot emitted per run (``radio.bytes_sent``), and the mean belief gap (``gap_mean``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import sys
from collections import Counter
from pathlib import Path

import numpy as np

import fleet_emu.agents.protocol as proto
from benchmarks._common import parser
from fleet_emu.core.errors import FleetError
from fleet_emu.core.grid import UNKNOWN
from fleet_emu.core.messages import Envelope, TxBundle, open_envelope
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.checks import check
from fleet_emu.launch.memory import Fleet

RECOVERY = ("mapfill", "resent_cells", "sync_fields")


def sync_overhead(env: Envelope) -> tuple[int, bool]:
    """The bytes map sync adds to a beacon or a delta (its fields), and whether a beacon carries a request."""
    if env.payload_kind not in ("pose", "map"):
        return 0, False
    body = open_envelope(env).body
    if isinstance(body, proto.PoseBeacon):
        beacon = proto.PoseBeacon(cell=body.cell, next=body.next)
        return len(env.payload) - len(beacon.encode()), getattr(body, "want", None) is not None
    if isinstance(body, proto.MapDelta):
        delta = proto.MapDelta(cells=body.cells, values=body.values)
        return len(env.payload) - len(delta.encode()), False
    return 0, False


def gaps(grids: list[np.ndarray]) -> tuple[float, int]:
    """Mean over ordered pairs of the cells one robot knows and the other does not; cells in conflict."""
    known = [g != UNKNOWN for g in grids]
    pairs, total, conflict = 0, 0, 0
    for i in range(len(grids)):
        for j in range(len(grids)):
            if i != j:
                pairs += 1
                total += int((known[j] & ~known[i]).sum())
                if i < j:
                    conflict += int((known[i] & known[j] & (grids[i] != grids[j])).sum())
    return (total / pairs if pairs else 0.0), conflict


def run_seed(scenario: Scenario, seed: int) -> dict:
    """One run: its result's main keys, the gap measures and the radio by payload kind."""
    count: Counter[str] = Counter()
    size: Counter[str] = Counter()

    def tap(_key: str, msg: object, _ns: int) -> None:
        if isinstance(msg, TxBundle):
            for env in msg.msgs:
                count[env.payload_kind] += 1
                size[env.payload_kind] += len(env.encode())
                extra, asks = sync_overhead(env)
                size["sync_fields"] += extra
                count["asks"] += asks

    fleet = Fleet(scenario, tap=tap)
    fleet.reset(seed)
    per_tick: list[float] = []
    while not fleet.done:
        fleet.step()
        grids = [b.belief.grid for b in fleet.brains.values() if b.belief is not None]
        per_tick.append(gaps(grids)[0])
    res = fleet.result()
    syncs = [s for b in fleet.brains.values() if (s := getattr(b, "sync", None)) is not None]
    size["resent_cells"] = 5 * sum(s.resent_cells for s in syncs)
    count["resent"] = sum(s.resent for s in syncs)
    gap_end, conflict = gaps([b.belief.grid for b in fleet.brains.values() if b.belief is not None])
    return {"seed": seed, "ticks": res["ticks"], "completed": res["completed"], "coverage": res["coverage"],
            "radio": res["radio"], "gap_end": gap_end, "gap_mean": float(np.mean(per_tick)) if per_tick else 0.0,
            "conflict": conflict, "count": dict(count), "bytes": dict(size)}


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.map_sync", __doc__)
    p.add_argument("--map", default="office")
    p.add_argument("--robots", type=int, default=3)
    p.add_argument("--allocator", default="minpos")
    p.add_argument("--loss", type=float, default=0.3)
    p.add_argument("--comm", default="full")
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--start", default="random", help="'random' (drawn per seed), 'map', or ROW,COL")
    p.add_argument("--max-ticks", type=int, default=3000)
    p.add_argument("--json", type=Path, help="write the per-seed rows here")
    p.add_argument("--switch", type=_losses, metavar="L,L,...",
                   help="one row per loss, map sync on against off (the scenario's map_sync), instead of --loss")
    a = p.parse_args(argv)
    start = None if a.start == "map" else a.start
    if isinstance(start, str) and "," in start:
        with contextlib.suppress(ValueError):  # else the scenario's check says what is wrong
            start = tuple(int(v) for v in start.split(","))
    try:
        base = Scenario().override(map=a.map, robots=a.robots, allocator=a.allocator, loss=a.loss, comm=a.comm,
                                   start=start, max_ticks=a.max_ticks, belief_every=0)
        check(base)  # the map, the allocator, the start area: before the table's first line
        switch(a, base) if a.switch else run(a, base)
    except FleetError as exc:  # bad input: one line, exit 2
        print(f"map_sync: error: {exc}", file=sys.stderr)
        sys.exit(2)


def run(a: argparse.Namespace, base: Scenario) -> None:
    """The runs and the table."""
    rows = []
    print(f"{a.map}, {a.robots} robots, {a.allocator}, comm {a.comm}, loss {a.loss}", file=sys.stderr)
    print(f"{'seed':>4} {'ticks':>6} {'gap_end':>8} {'gap_mean':>8} {'conflict':>8} {'sent':>7} {'bytes':>9}"
          f" {'asks':>5} {'resent':>6} {'fills':>5} {'rec.bytes':>9}")
    for seed in range(a.seeds):
        r = run_seed(base, seed)
        rows.append(r)
        rec_b = sum(r["bytes"].get(k, 0) for k in RECOVERY)
        flag = "" if r["completed"] else "*"
        print(f"{seed:>4} {r['ticks']:>5}{flag:1} {r['gap_end']:>8.1f} {r['gap_mean']:>8.1f} {r['conflict']:>8}"
              f" {r['radio']['sent']:>7} {r['radio']['bytes_sent']:>9} {r['count'].get('asks', 0):>5}"
              f" {r['count'].get('resent', 0):>6} {r['count'].get('mapfill', 0):>5} {rec_b:>9}", flush=True)
    mean = statistics.mean
    kinds = sorted({k for r in rows for k in r["bytes"]})
    print(f"mean {mean(r['ticks'] for r in rows):>6.1f} {mean(r['gap_end'] for r in rows):>8.1f}"
          f" {mean(r['gap_mean'] for r in rows):>8.1f} {mean(r['conflict'] for r in rows):>8.1f}"
          f" {mean(r['radio']['sent'] for r in rows):>7.0f} {mean(r['radio']['bytes_sent'] for r in rows):>9.0f}"
          f"  ({sum(not r['completed'] for r in rows)} runs short of the target)")
    recovery = mean(sum(r["bytes"].get(k, 0) for k in RECOVERY) for r in rows)
    print(f"recovery bytes per run {recovery:.0f}; per run by kind (and messages): " + ", ".join(
        f"{k} {mean(r['bytes'].get(k, 0) for r in rows):.0f} ({mean(r['count'].get(k, 0) for r in rows):.0f} msgs)"
        for k in kinds))
    if a.json:
        a.json.write_text(json.dumps({"args": vars(a) | {"json": str(a.json)}, "rows": rows}, indent=1))


def _losses(text: str) -> list[float]:
    """``--switch``: loss probabilities, comma-separated, each in [0, 1]."""
    try:
        out = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of numbers: {text!r}") from None
    if not out or any(not 0 <= v <= 1 for v in out):
        raise argparse.ArgumentTypeError(f"each loss must be in [0, 1] (got {text!r})")
    return out


def switch(a: argparse.Namespace, base: Scenario) -> None:
    """``--switch``: per loss, the same seeds with map sync on and off; ticks, their change from the first
    loss, kilobytes sent per run and the mean belief gap."""
    print(f"{a.map}, {a.robots} robots, {a.allocator}, comm {a.comm}, {a.seeds} seeds, start {a.start}",
          file=sys.stderr)
    print("| loss | ticks, sync on | off | vs first loss, on | off | kB sent per run, on | off "
          "| belief gap, on | off | runs short, on | off |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    mean = statistics.mean
    first: dict[bool, float] = {}
    for loss in a.switch:
        cols: dict[bool, list[dict]] = {}
        for on in (True, False):
            s = base.override(loss=loss, map_sync=on)
            cols[on] = [run_seed(s, seed) for seed in range(a.seeds)]
        ticks = {on: mean(r["ticks"] for r in rows) for on, rows in cols.items()}
        first = first or ticks
        vs = {on: 100.0 * (ticks[on] - first[on]) / first[on] for on in cols}
        kb = {on: mean(r["radio"]["bytes_sent"] for r in rows) / 1e3 for on, rows in cols.items()}
        gap = {on: mean(r["gap_mean"] for r in rows) for on, rows in cols.items()}
        short = {on: sum(not r["completed"] for r in rows) for on, rows in cols.items()}
        print(f"| {loss:g} | {ticks[True]:.1f} | {ticks[False]:.1f} | {vs[True]:+.1f} % | {vs[False]:+.1f} % "
              f"| {kb[True]:.0f} | {kb[False]:.0f} | {gap[True]:.0f} | {gap[False]:.0f} "
              f"| {short[True]} | {short[False]} |", flush=True)


if __name__ == "__main__":
    main()
