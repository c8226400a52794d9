"""Memory of the robot processes: PSS and RSS per agent, sampled from ``/proc/PID/smaps_rollup`` while a run goes.

    python -m benchmarks.agent_memory [--robots 16 32] [--ticks 40] [--map office] [-- FLEET RUN FLAGS...]

Starts ``fleet run`` and, every ``--period`` seconds until it ends, reads ``smaps_rollup`` of every process
under the launcher. Once the run has ended, ``result.json``'s pids say which were the agents; the rest but the
world and netem is the fork server (when there is one). PSS (proportional set size) divides each shared page
among the processes that map it, so the PSS of the agents plus the fork server adds up to what they cost the
machine; RSS counts every shared page in full in every process. Per agent the peak over the run is kept; the
table gives their mean and max, the fork server's peak PSS, and the peak of the agents' and fork server's summed
PSS at one sample. Flags after ``--`` go to ``fleet run`` (e.g. ``-- --no-fork-server`` for the old way).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks._common import ROOT, fleet_command, parser, smaps_rollup


def children_map() -> dict[int, list[int]]:
    """Every process's children, from ``/proc/*/stat``."""
    kids: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        kids.setdefault(ppid, []).append(int(entry))
    return kids


def descendants(root: int) -> list[int]:
    kids = children_map()
    out: list[int] = []
    todo = list(kids.get(root, []))
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo += kids.get(pid, [])
    return out


def measure(robots: int, ticks: int, map_name: str, period: float, extra: list[str]) -> dict[str, Any] | None:
    """One run: per-pid peak PSS and RSS, the peak summed PSS per sample, and result.json's pids."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = fleet_command(["--map", map_name, "--robots", str(robots), "--max-ticks", str(ticks),
                             "--target-coverage", "1.0", *extra], out)
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        peak: dict[int, tuple[int, int]] = {}
        samples: list[dict[int, int]] = []
        while proc.poll() is None:
            sample: dict[int, int] = {}
            for pid in descendants(proc.pid):
                got = smaps_rollup(pid)
                if got is not None:
                    pss, rss = got.get("Pss", 0), got.get("Rss", 0)
                    sample[pid] = pss
                    old = peak.get(pid, (0, 0))
                    peak[pid] = (max(old[0], pss), max(old[1], rss))
            samples.append(sample)
            time.sleep(period)
        err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
        if proc.returncode not in (0, 3) or not (out / "result.json").exists():
            print(f"{robots} robots: fleet run exited {proc.returncode}: {err.strip()[-300:]}", file=sys.stderr)
            return None
        res = json.loads((out / "result.json").read_text())
    agents = set(res["pids"]["robots"])
    others = {res["pids"]["world"], res["pids"]["netem"]}
    server = [p for p in peak if p not in agents and p not in others]
    summed, at = max(((sum(v for p, v in s.items() if p in agents or p in server), s) for s in samples),
                     key=lambda x: x[0], default=(0, {}))
    return {"robots": robots, "ticks": res["ticks"], "agents": [peak.get(p, (0, 0)) for p in sorted(agents)],
            "server": sum(at.get(p, 0) for p in server), "summed": summed}


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.agent_memory", __doc__)
    p.add_argument("--robots", type=int, nargs="+", default=[16, 32])
    p.add_argument("--ticks", type=int, default=40)
    p.add_argument("--map", default="office")
    p.add_argument("--period", type=float, default=0.5, help="seconds between samples")
    argv = sys.argv[1:] if argv is None else argv
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = p.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    print(f"{'robots':>6} {'ticks':>5} {'agent PSS mean MB':>17} {'max MB':>7} {'agent RSS mean MB':>17} "
          f"{'fork server PSS MB':>18} {'agents+server PSS MB':>20}")
    failed = False
    for i, n in enumerate(a.robots, 1):
        r = measure(n, a.ticks, a.map, a.period, extra)
        if r is None:
            failed = True
            print(f"[{i}/{len(a.robots)}] {n} robots: FAILED", file=sys.stderr, flush=True)
            print(f"{n:>6} {'failed':>5}")
            continue
        print(f"[{i}/{len(a.robots)}] {n} robots: {r['ticks']} ticks", file=sys.stderr, flush=True)
        if not all(x[0] for x in r["agents"]):  # a robot never sampled: the run ended between two samples
            failed = True
            print(f"{n:>6} {r['ticks']:>5} not sampled: the run ended too soon (more --ticks, or a shorter --period)")
            continue
        pss = [x[0] / 1024 for x in r["agents"]]
        rss = [x[1] / 1024 for x in r["agents"]]
        print(f"{n:>6} {r['ticks']:>5} {sum(pss) / len(pss):>17.1f} {max(pss):>7.1f} {sum(rss) / len(rss):>17.1f} "
              f"{r['server'] / 1024:>18.1f} {r['summed'] / 1024:>20.1f}", flush=True)
    raise SystemExit(1 if failed else 0)


if __name__ == "__main__":
    main()
