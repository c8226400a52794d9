"""The launcher's memory and stderr under stalled live viewers: ``fleet run --live`` (memory engine, 8 robots on
autolab at 0.05 m cells, ``--live-hz 10``: large grids, so a viewer that stops reading fills its socket within
seconds) watched by nobody, then by ``--viewers`` viewers that subscribe to every channel and never read again
(``tests/harness/stalled_viewer.py``), connected mid-run (``--delay`` seconds after the run's live line) in
``--waves`` waves (a new wave once the previous one has been dropped). Each seed is run both ways (paired by
seed).

Prints one row per seed and mode: the launcher's peak RSS (``VmHWM``, MB), its stderr lines, the viewers it
reported dropped (``live: dropped the viewer at ...``) and the distinct ones among them; then the mean
difference in peak RSS with a 95% t interval over the seeds."""

from __future__ import annotations

import re
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from benchmarks._common import ROOT, machine, parser
from tests.harness.stalled_viewer import stall

BIG = ("--engine", "memory", "--map", "autolab", "--robots", "8", "--cell-size", "0.05", "--target-coverage",
       "1.0", "--live", "127.0.0.1:0", "--live-hz", "10", "--quiet")
T95 = {1: 12.71, 2: 4.30, 3: 3.18, 4: 2.78, 5: 2.57, 6: 2.45, 7: 2.36, 8: 2.31, 9: 2.26}
DROPPED = re.compile(r"live: dropped the viewer at (\S+)")


def _hwm_kb(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def one(seed: int, ticks: int, viewers: int, waves: int, delay: float = 3.0) -> dict[str, int]:
    """One run; its peak RSS (kB), stderr lines and the drops it reported."""
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "run", *BIG, "--max-ticks", str(ticks),
                                 "--seed", str(seed), "--out", str(Path(tmp) / "run")], cwd=ROOT,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        assert proc.stderr is not None
        first = proc.stderr.readline()
        lines = [first]
        reader = threading.Thread(target=lambda: lines.extend(proc.stderr or ()), daemon=True)
        reader.start()
        url = re.search(r"live: (ws://\S+)", first)
        if url is None:
            print(f"live_viewers: no live URL from the run: {first.strip()}", file=sys.stderr)
        peak = 0
        socks: list[socket.socket] = []
        try:
            start = time.monotonic()
            while viewers and proc.poll() is None and time.monotonic() - start < delay:
                peak = max(peak, _hwm_kb(proc.pid) or 0)
                time.sleep(0.1)
            for _ in range(waves if url and viewers else 0):
                before = sum(len(DROPPED.findall(s)) for s in list(lines))
                for _ in range(viewers):
                    try:
                        socks.append(stall(url.group(1), 5, timeout=20))  # type: ignore[union-attr]
                    except OSError:
                        break
                while proc.poll() is None and sum(len(DROPPED.findall(s)) for s in list(lines)) < before + viewers:
                    peak = max(peak, _hwm_kb(proc.pid) or 0)
                    time.sleep(0.1)
            while proc.poll() is None:
                peak = max(peak, _hwm_kb(proc.pid) or 0)
                time.sleep(0.1)
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
            for s in socks:
                s.close()
        reader.join(10)
    text = "".join(lines)
    drops = DROPPED.findall(text)
    return {"peak_kb": peak, "lines": text.count("\n"), "drops": len(drops), "distinct": len(set(drops)),
            "code": proc.returncode}


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.live_viewers", __doc__)
    p.add_argument("--viewers", type=int, default=20, help="stalled viewers in each wave (default 20)")
    p.add_argument("--waves", type=int, default=1, help="waves of viewers (default 1)")
    p.add_argument("--ticks", type=int, default=120, help="ticks of each run, at 10 a second (default 120)")
    p.add_argument("--seeds", type=int, default=3, help="seeds, each run without and with viewers (default 3)")
    p.add_argument("--delay", type=float, default=3.0,
                   help="seconds after the run's live line before the first wave connects (default 3)")
    a = p.parse_args(argv)
    if a.viewers < 1 or a.waves < 1 or a.ticks < 1 or a.seeds < 1 or not 0 <= a.delay <= 600:
        p.error("--viewers, --waves, --ticks and --seeds must be at least 1, --delay from 0 to 600")
    print(machine())
    print(f"{'seed':>4} {'viewers':>8} {'peak MB':>8} {'stderr lines':>12} {'drops':>6} {'distinct':>8} {'exit':>5}")
    diffs = []
    for seed in range(a.seeds):
        peaks = []
        for n in (0, a.viewers):
            r = one(seed, a.ticks, n, a.waves, a.delay)
            peaks.append(r["peak_kb"] / 1024)
            print(f"{seed:>4} {n * a.waves:>8} {peaks[-1]:>8.0f} {r['lines']:>12} {r['drops']:>6} {r['distinct']:>8} "
                  f"{r['code']:>5}", flush=True)
        diffs.append(peaks[1] - peaks[0])
    mean = statistics.mean(diffs)
    half = T95[len(diffs) - 1] * statistics.stdev(diffs) / len(diffs) ** 0.5 if len(diffs) > 1 else float("nan")
    print(f"peak RSS with {a.viewers} x {a.waves} stalled viewers minus without: {mean:.0f} MB "
          f"(95% CI +/- {half:.0f} MB, n={len(diffs)} seeds)")


if __name__ == "__main__":
    main()
