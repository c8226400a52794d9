"""What the benchmark scripts share: one-line argument errors, the machine's header line, the real maps' paths,
maps fitted to a size, a ``fleet run`` subprocess, ``/proc`` readings and the mean ± sd cell of a table.

The scripts run as modules from the repository root (``python -m benchmarks.scale ...``, see
``benchmarks/README.md``), so they import this module and one another as ``benchmarks.<name>``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, NoReturn

ROOT = Path(__file__).resolve().parents[1]
#: Stage's real maps, read where they lie beside the repository (scripts fall back or say so when absent).
#: Registry maps (`fleet maps fetch cave hospital_section` once).
REAL_MAP = "cave"
HOSPITAL = "hospital_section"
Cell = tuple[int, int]


# --- arguments and errors --------------------------------------------------------------------------------

def fail(prog: str, message: str) -> NoReturn:
    """Bad input: one line, ``PROG: error: MESSAGE``, and exit 2."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, ``NAME: error: ...``, and exit 2 (``fail``); NAME is the
    script's (``scale`` for ``prog="python -m benchmarks.scale"``)."""

    def error(self, message: str) -> NoReturn:
        fail(self.prog.split()[-1].removeprefix("benchmarks."), message)


def parser(module: str, doc: str | None, full: bool = True) -> OneLineParser:
    """The script's parser: ``prog`` its module name (``benchmarks.scale``), its docstring as the help (the
    whole of it with ``full``, else its first line)."""
    text = doc or ""
    return OneLineParser(prog=f"python -m {module}", description=text if full else text.split("\n\n")[0],
                         formatter_class=argparse.RawDescriptionHelpFormatter)


def engine_arguments(p: argparse.ArgumentParser) -> None:
    """``--in-process`` and ``--engine`` for a script whose runs are ``fleet run`` subprocesses (``engine_flags``)."""
    p.add_argument("--in-process", action="store_true", help="all nodes of a run in one process, over Zenoh")
    p.add_argument("--engine", choices=("processes", "memory"), default="processes",
                   help="memory: the memory engine, the processes engine's results for a seed at a fraction of "
                        "the CPU (no Zenoh, no processes)")


def engine_flags(a: argparse.Namespace) -> list[str]:
    """The ``fleet run`` flags of ``engine_arguments``' choice (``--in-process`` and ``--engine memory`` are one
    engine each: the memory engine wins)."""
    if a.engine == "memory":
        return ["--engine", "memory"]
    return ["--in-process"] if a.in_process else []


def machine() -> str:
    """Cores, memory, CPU model and load: the header line of a table."""
    model = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                  if ln.startswith("model name")), platform.machine())
    mem_kb = next(int(ln.split()[1]) for ln in Path("/proc/meminfo").read_text().splitlines()
                  if ln.startswith("MemTotal:"))
    load = " ".join(f"{v:.2f}" for v in os.getloadavg())
    return (f"{os.cpu_count()} cores ({model}), {mem_kb / 2**20:.1f} GiB memory, load average {load} at start, "
            f"Python {platform.python_version()}, {platform.system()} {platform.release()}")


def mean_sd(values: Sequence[float | None], digits: int = 3) -> str:
    """``mean ± sd`` (sample sd; 0 for one value) of a table cell; ``-`` when empty or a value is missing."""
    if not values or any(v is None for v in values):
        return "-"
    xs = [float(v) for v in values if v is not None]
    sd = statistics.stdev(xs) if len(xs) > 1 else 0.0
    return f"{statistics.fmean(xs):.{digits}f} ± {sd:.{digits}f}"


# --- maps fitted to a size -------------------------------------------------------------------------------

def fit_cell_size(name: str, cells: int, seed: int) -> tuple[float, Cell]:
    """The cell size that makes ``name`` (a built-in map or a file) about ``cells`` cells across (its larger
    side), and the map's shape there: a few rescaling steps, then a scan of +-5 % around the best."""
    from fleet_emu.world.maps import load_map

    def shape(cs: float) -> Cell:
        g = load_map(name, cs, seed).grid
        return int(g.shape[0]), int(g.shape[1])

    tried: dict[float, Cell] = {}
    cs = 0.5
    for _ in range(4):
        tried[cs] = shape(cs)
        cs = cs * max(tried[cs]) / cells
    best = min(tried, key=lambda c: abs(max(tried[c]) - cells))
    for k in range(-5, 6):
        c = round(best * (1 + k / 100), 6)
        if c not in tried:
            tried[c] = shape(c)
    best = min(tried, key=lambda c: (abs(max(tried[c]) - cells), abs(c - best)))
    return best, tried[best]


def open_start(name: str, cs: float, seed: int) -> Cell:
    """The start cell of every run on this map: in the main free component (the map's own start's), the cell
    with the most free cells within the world's start radius (Manhattan), the nearest the map's start first."""
    import numpy as np
    from scipy import ndimage

    from fleet_emu.core.grid import FREE
    from fleet_emu.world.maps import load_map
    from fleet_emu.world.sim import WorldConfig

    md = load_map(name, cs, seed)
    free = md.grid == FREE
    labels, _ = ndimage.label(free)
    main = labels == labels[md.start]
    r = WorldConfig().start_radius
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    diamond = (np.abs(yy) + np.abs(xx) <= r).astype(np.int32)
    room = np.where(main, ndimage.correlate(free.astype(np.int32), diamond, mode="constant"), -1)
    rows, cols = np.nonzero(room == room.max())
    k = int(np.argmin((rows - md.start[0]) ** 2 + (cols - md.start[1]) ** 2))
    return int(rows[k]), int(cols[k])


@dataclasses.dataclass(frozen=True)
class FittedMap:
    """A map drawn about ``cells`` cells across (:func:`fit_cell_size`) and its most open start cell."""

    name: str  # as given: a built-in name or a file
    label: str  # its stem, for the table
    cell_size: float
    shape: Cell
    start: Cell

    @property
    def cells(self) -> str:
        return f"{self.shape[0]}x{self.shape[1]}"


def fitted_maps(prog: str, names: Iterable[str], cells: int, seed: int) -> list[FittedMap]:
    """Every map fitted, each said on stderr; a map that cannot be read is bad input (``fail``)."""
    from fleet_emu.core.errors import FleetError

    out = []
    for name in names:
        try:
            cs, shape = fit_cell_size(name, cells, seed)
            start = open_start(name, cs, seed)
        except FleetError as exc:
            fail(prog, f"map {name}: {exc}")
        out.append(FittedMap(name, Path(name).stem, cs, shape, start))
        print(f"map {name}: {shape[0]} x {shape[1]} cells at {cs:.5g} m, start {start}", file=sys.stderr, flush=True)
    return out


def fitted_scenario(m: FittedMap, robots: int, seed: int, sensor_cells: float, comm_cells: float,
                    allocator: dict[str, Any], **over: Any) -> Any:
    """The default scenario (``launch/scenarios/default.toml``) on a fitted map, from its open start, with the
    sensor and comm ranges in cells and ``allocator``; ``over``: more scenario fields."""
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.cli import DEFAULT_SCENARIO

    cs = m.cell_size
    sc = Scenario.load(DEFAULT_SCENARIO).override(
        map=m.name, cell_size=cs, robots=robots, start=m.start, seed=seed, sensor_range=sensor_cells * cs,
        comm_range=comm_cells * cs, **over)
    return dataclasses.replace(sc, allocator=dict(allocator)).validate()


# --- processes ---------------------------------------------------------------------------------------------

def fleet_command(args: Sequence[str], out: Path) -> list[str]:
    """``fleet run ARGS --quiet --no-record --out OUT`` as this interpreter runs it."""
    return [sys.executable, "-m", "fleet_emu.launch", "run", *args, "--quiet", "--no-record", "--out", str(out)]


def fleet_run(args: Sequence[str]) -> dict[str, Any]:
    """One ``fleet run ARGS`` in a subprocess; its ``result.json``, or ``{"error": LAST STDERR LINE, "code":
    EXIT}`` when it did not end normally (an exit code other than 0 or 3: bad input, or a process of the fleet,
    a robot too, failed)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        proc = subprocess.run(fleet_command(args, out), cwd=ROOT, capture_output=True, text=True, check=False)
        if proc.returncode not in (0, 3) or not (out / "result.json").exists():
            lines = proc.stderr.strip().splitlines()
            return {"error": lines[-1][:300] if lines else "no output", "code": proc.returncode}
        data: dict[str, Any] = json.loads((out / "result.json").read_text())
        return data


def smaps_rollup(pid: int) -> dict[str, int] | None:
    """``/proc/PID/smaps_rollup``'s ``Pss`` and ``Rss`` in kB; None once the process is gone."""
    try:
        text = Path(f"/proc/{pid}/smaps_rollup").read_text()
    except OSError:
        return None
    out = {}
    for line in text.splitlines():
        key = line.split(":", 1)[0]
        if key in ("Pss", "Rss"):
            out[key] = int(line.split()[1])
    return out
