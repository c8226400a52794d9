"""Time to refuse each untrusted input, and time to stop on SIGTERM or SIGINT in each wait, as a user meets them.

    python -m benchmarks.bad_inputs                  # every case, 5 times each (the silent scheduler 3 times)
    python -m benchmarks.bad_inputs --runs 3 --cases fifo-scenario zip-bomb

Each case runs the ``fleet`` command an adversary's file or peer makes a user run (a fresh interpreter, as the
console script), and reports its exit code, the seconds from its start to its exit (median and range over the
runs: the interpreter's own start-up, about 2-3 s on a loaded 2-core machine, is most of it) and the command's
peak resident memory (``wait4``'s ``ru_maxrss``: the whole process, Python and its imports included). A
``stop-*`` case sends its signal once the command waits (``--after`` seconds after its start) and reports the
seconds from the signal to the exit. The inputs are made in a temporary folder; the silent scheduler is a
loopback socket that accepts and never answers.
"""

from __future__ import annotations

import argparse
import io
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests.harness.files import crafted
from tests.harness.peers import silent_peer

RUN = ["run", "--engine", "memory", "--map", "office", "--robots", "2", "--max-ticks", "30", "--quiet"]
POLICY = [*RUN, "--allocator", "policy", "--param"]


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array)
    return buf.getvalue()


def _policy(folder: Path, name: str, weights: np.ndarray | None = None, zeros: int = 0) -> Path:
    """A policy file: ``weights``, or (``zeros``) a bomb whose weights are that many float64 zeros, written a
    megabyte at a time so that this process stays small (its children start as a copy of it)."""
    from fleet_emu.agents.allocators.policy import FEATURES

    path = folder / name
    if path.exists():
        return path
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        if zeros:
            with z.open("weights.npy", "w", force_zip64=True) as f:
                header = io.BytesIO()
                np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                              "shape": (zeros,)})
                f.write(header.getvalue())
                block = bytes(1 << 20)
                for start in range(0, zeros * 8, len(block)):
                    f.write(block[:min(len(block), zeros * 8 - start)])
        else:
            z.writestr("weights.npy", _npy(np.asarray(weights)))
        z.writestr("k.npy", _npy(np.array(8, dtype=np.int64)))
        z.writestr("features.npy", _npy(np.array(FEATURES)))
    return path


def _fifo(folder: Path, name: str) -> Path:
    path = folder / name
    if not path.exists():
        os.mkfifo(path)
    return path


def _linked_out(folder: Path) -> Path:
    out = folder / "linked"
    if not out.exists():
        out.mkdir()
        (folder / "victim").write_text("precious")
        for name in ("r0.log", "world.log", "router.log", "forkserver.log", ".fleet.lock"):
            (out / name).symlink_to(folder / "victim")
    return out


def _small_study(folder: Path) -> Path:
    path = folder / "small.toml"
    path.write_text('[study]\nname = "small"\n[grid]\nrobots = [2]\n[fleet]\nmap = "office"\nmax_ticks = 30\n')
    return path


def _huge_study(folder: Path) -> Path:
    path = folder / "huge.toml"
    grid = "\n".join(f"k{i} = [{', '.join(map(str, range(10)))}]" for i in range(10))
    path.write_text(f'[study]\nname = "huge"\n[grid]\n{grid}\n')
    return path


def _recording(folder: Path, name: str, scenario: object) -> Path:
    """An MCAP file of a few hundred bytes: only the ``scenario`` metadata a recording starts with."""
    path = folder / name
    return path if path.exists() else crafted(path, scenario)


def _cut_run(folder: Path) -> Path:
    """A finished run's folder (memory engine, 200 ticks) whose run.mcap is cut in half, its result.json kept."""
    out = folder / "half"
    if not out.exists():
        from fleet_emu.core.scenario import Scenario
        from fleet_emu.launch.memory import run_memory

        run_memory(Scenario().override(map="office", robots=3, seed=1, max_ticks=200), out, run_id="half")
        data = (out / "run.mcap").read_bytes()
        (out / "run.mcap").write_bytes(data[: len(data) // 2])
    return out


BIG = {"robots": 100_000_000, "cell_size": 1.0, "map": "office"}

#: name -> the command's arguments, made from the temporary folder and the silent peer's address.
CASES: dict[str, Callable[[Path, str], list[str]]] = {
    "bad-flag": lambda d, _: [*RUN, "--robots", "0"],
    "linked-out": lambda d, _: ["run", "--map", "office", "--robots", "2", "--out", str(_linked_out(d))],
    "fifo-scenario": lambda d, _: ["run", "--scenario", str(_fifo(d, "s.toml")), "--engine", "memory"],
    "fifo-policy": lambda d, _: [*POLICY, f"path={_fifo(d, 'p.npz')}"],
    "dev-zero-policy": lambda d, _: [*POLICY, "path=/dev/zero"],
    "zip-bomb": lambda d, _: [*POLICY, f"path={_policy(d, 'bomb.npz', zeros=50_000_000)}"],
    "weights-1e308": lambda d, _: [*POLICY, f"path={_policy(d, 'huge.npz', np.full(5, 1e308))}"],
    "fifo-study": lambda d, _: ["sweep", str(_fifo(d, "study.toml"))],
    "recording-1e8-robots": lambda d, _: ["report", str(_recording(d, "big.mcap", BIG)), "--no-plots"],
    "recording-1e8-robots-export": lambda d, _: ["export", "ros2", str(_recording(d, "big.mcap", BIG))],
    "recording-list-export": lambda d, _: ["export", "ros2", str(_recording(d, "list.mcap", [1, 2, 3]))],
    "recording-cut-half": lambda d, _: ["report", str(_cut_run(d)), "--no-plots"],
    "recording-cut-half-export": lambda d, _: ["export", "ros2", str(_cut_run(d))],
    "grid-1e10": lambda d, _: ["sweep", str(_huge_study(d))],
    "silent-scheduler": lambda d, peer: ["sweep", str(_small_study(d)), "--dask", peer],
    "stop-sigterm-silent-scheduler": lambda d, peer: ["sweep", str(_small_study(d)), "--dask", peer],
    "stop-sigint-silent-scheduler": lambda d, peer: ["sweep", str(_small_study(d)), "--dask", peer],
    "stop-sigterm-run": lambda d, _: ["run", "--map", "office", "--robots", "3", "--max-ticks", "100000",
                                      "--target-coverage", "1.0", "--quiet", "--no-record"],
    "stop-sigterm-memory-run": lambda d, _: [*RUN[:-3], "--max-ticks", "100000", "--target-coverage", "1.0",
                                             "--quiet", "--no-record"],
}


#: Runs the command and prints its peak RSS (kB): a small parent, as a child's peak RSS counts what it was a copy
#: of before its exec. The command starts with SIGINT and SIGTERM at their defaults, as in a terminal's
#: foreground (a shell's background job ignores SIGINT), and gets them when it does; SIGUSR1 kills its group.
_WRAPPER = """
import os, signal, sys
quiet = [(os.POSIX_SPAWN_OPEN, fd, os.devnull, os.O_WRONLY, 0) for fd in (1, 2)]
pid = os.posix_spawn(sys.executable, [sys.executable, "-m", "fleet_emu", *sys.argv[1:]], os.environ,
                     setsid=True, setsigdef=(signal.SIGINT, signal.SIGTERM), file_actions=quiet)
for sig in (signal.SIGINT, signal.SIGTERM):
    signal.signal(sig, lambda s, _f: os.kill(pid, s))
signal.signal(signal.SIGUSR1, lambda _s, _f: os.killpg(pid, signal.SIGKILL))
while True:
    try:
        _, status, usage = os.wait4(pid, 0)
        break
    except InterruptedError:
        continue
print(os.waitstatus_to_exitcode(status), usage.ru_maxrss, flush=True)
"""


def measure(argv: list[str], out: Path, signum: int | None, after: float, limit: float) -> tuple[int, float, int]:
    """One command: its exit code, the seconds to its exit (from its start, or from ``signum`` sent ``after``
    seconds in) and its peak RSS in MB. Killed (and reported as exit -9) past ``limit`` seconds."""
    argv = argv if "--out" in argv or argv[0] == "report" else [*argv, "--out", str(out)]
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-S", "-c", _WRAPPER, *argv], stdout=subprocess.PIPE, text=True)
    sent = None
    while proc.poll() is None:
        now = time.monotonic()
        if signum is not None and sent is None and now - t0 >= after:
            proc.send_signal(signum)
            sent = now
        if now - t0 > limit:
            proc.send_signal(signal.SIGUSR1)
            limit = float("inf")
        time.sleep(0.01)
    end = time.monotonic()
    assert proc.stdout is not None
    code, rss = proc.stdout.read().split()
    return int(code), end - (sent if sent is not None else t0), int(rss) // 1024


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="runs of each case (the silent scheduler's: at most 3)")
    ap.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES), metavar="CASE",
                    help=f"the cases (default all: {', '.join(CASES)})")
    ap.add_argument("--after", type=float, default=8.0,
                    help="seconds before a stop-* case's signal (the command's start-up is 3-5 s)")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    print("| case | runs | exit codes | seconds (median) | seconds (min-max) | peak RSS MB (max) |")
    print("| --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory(prefix="bad-inputs-") as tmp, silent_peer() as peer:
        folder = Path(tmp)
        for name in args.cases:
            runs = min(args.runs, 3) if "scheduler" in name else args.runs
            signum = signal.SIGINT if "sigint" in name else signal.SIGTERM if name.startswith("stop-") else None
            rows = []
            for i in range(runs):
                cmd = CASES[name](folder, peer)
                rows.append(measure(cmd, folder / f"out-{name}-{i}", signum, args.after, 120.0))
                print(f"{name} run {i + 1}: exit {rows[-1][0]}, {rows[-1][1]:.2f} s", file=sys.stderr)
            secs = [r[1] for r in rows]
            codes = ",".join(sorted({str(r[0]) for r in rows}))
            print(f"| {name} | {runs} | {codes} | {statistics.median(secs):.2f} | {min(secs):.2f}-{max(secs):.2f} "
                  f"| {max(r[2] for r in rows)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
