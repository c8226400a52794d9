"""The test suite's CPU: the whole run's user + sys seconds, and the tests and modules that cost the most.

    python -m benchmarks.suite_cost [--top 15] [--json FILE] [-- PYTEST ARGS...]

Runs ``python -m pytest`` (the default suite, or the arguments after ``--``, e.g. ``-- -m slow`` or
``-- tests/integration``) in a child process with this module as a pytest plugin. The plugin reads
``resource.getrusage`` of ``RUSAGE_SELF`` and ``RUSAGE_CHILDREN`` (user + sys) before and after each test's setup,
call and teardown: the test's CPU is the pytest process's own plus that of every process it started and waited
for (a fleet's launcher, world, netem and robots, a ``fleet`` subprocess); a session or module fixture counts
in the first test that asks for it. The total is the pytest child's whole CPU as this script reaps it
(collection and start-up included). CPU seconds, not wall time, are the figure to quote: a loaded machine
stretches the wall clock, much less the CPU a test spends. The table gives the total, the tests' count by
outcome, then the top tests and the top modules by CPU. The exit code is pytest's.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

from benchmarks._common import ROOT, machine, parser

_OUT = "FLEET_SUITE_COST_OUT"  # where the plugin (in the pytest child) writes its rows


def _cpu() -> float:
    """User + sys seconds of this process and of its waited-for children."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


# --- the plugin, loaded in the pytest child with ``-p benchmarks.suite_cost`` --------------------------------

_rows: list[dict[str, Any]] = []
_outcomes: dict[str, str] = {}


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: Any, nextitem: Any) -> Generator[None, None, None]:
    """Around one test's setup, call and teardown: its CPU and wall seconds."""
    cpu, wall = _cpu(), time.monotonic()
    yield
    _rows.append({"nodeid": item.nodeid, "cpu": _cpu() - cpu, "wall": time.monotonic() - wall})



def pytest_runtest_logreport(report: Any) -> None:
    """The test's outcome: failed if any phase failed, else skipped if skipped, else passed."""
    if report.failed:
        _outcomes[report.nodeid] = "failed"
    elif report.skipped and _outcomes.get(report.nodeid) != "failed":
        _outcomes[report.nodeid] = "skipped"
    else:
        _outcomes.setdefault(report.nodeid, "passed")


def pytest_sessionfinish(session: Any, exitstatus: int) -> None:
    """Write the rows for the script (only when the script started this pytest)."""
    path = os.environ.get(_OUT)
    if path:
        for row in _rows:
            row["outcome"] = _outcomes.get(row["nodeid"], "passed")
        Path(path).write_text(json.dumps(_rows))


# --- the script ----------------------------------------------------------------------------------------------

def run_suite(pytest_args: list[str]) -> tuple[int, float, float, list[dict[str, Any]]]:
    """Run pytest with the plugin: (its exit code, its whole CPU seconds, wall seconds, the per-test rows)."""
    with tempfile.TemporaryDirectory(prefix="suite-cost-") as tmp:
        out = Path(tmp) / "rows.json"
        before, wall = _children_cpu(), time.monotonic()
        try:  # pytest's own output goes to stderr as it comes, where stderr is a file
            sink: Any = sys.stderr.fileno()
        except (AttributeError, OSError, ValueError):  # (a captured stderr: given whole at the end)
            sink = subprocess.PIPE
        done = subprocess.run([sys.executable, "-m", "pytest", "-p", "benchmarks.suite_cost", *pytest_args],
                              cwd=ROOT, env={**os.environ, _OUT: str(out)}, stdout=sink, text=True)
        if done.stdout:
            sys.stderr.write(done.stdout)
        code = done.returncode
        cpu, wall = _children_cpu() - before, time.monotonic() - wall
        rows = json.loads(out.read_text()) if out.is_file() else []
    return code, cpu, wall, rows


def _children_cpu() -> float:
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return kids.ru_utime + kids.ru_stime


def table(cpu: float, wall: float, rows: list[dict[str, Any]], top: int) -> str:
    """The total, the counts by outcome, the top tests and the top modules by CPU, as markdown."""
    counts: dict[str, int] = defaultdict(int)
    modules: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])
    for r in rows:
        counts[r["outcome"]] += 1
        m = modules[r["nodeid"].split("::")[0]]
        m[0] += r["cpu"]
        m[1] += 1
    tests_cpu = sum(r["cpu"] for r in rows)
    lines = [f"suite: {len(rows)} tests ({', '.join(f'{v} {k}' for k, v in sorted(counts.items()))}), "
             f"{cpu:.0f} CPU s user+sys in all ({tests_cpu:.0f} in the tests, the rest collection and "
             f"start-up), {wall:.0f} s wall", "",
             f"| top {top} tests | CPU s | wall s |", "| --- | ---: | ---: |"]
    lines += [f"| `{r['nodeid']}` | {r['cpu']:.1f} | {r['wall']:.1f} |"
              for r in sorted(rows, key=lambda r: -r["cpu"])[:top]]
    lines += ["", f"| top {top} modules | CPU s | tests |", "| --- | ---: | ---: |"]
    lines += [f"| `{name}` | {c:.1f} | {n:.0f} |"
              for name, (c, n) in sorted(modules.items(), key=lambda kv: -kv[1][0])[:top]]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    args = list(sys.argv[1:] if argv is None else argv)
    ours, pytest_args = (args[:args.index("--")], args[args.index("--") + 1:]) if "--" in args else (args, [])
    p = parser("benchmarks.suite_cost", __doc__)
    p.add_argument("--top", type=int, default=15, help="how many tests and modules to list (default 15)")
    p.add_argument("--json", type=Path, help="also write the per-test rows (nodeid, cpu, wall, outcome) here")
    a = p.parse_args(ours)
    if a.top < 1:
        p.error(f"--top must be at least 1, not {a.top}")
    print(machine())
    code, cpu, wall, rows = run_suite(pytest_args)
    if not rows:
        print(f"pytest exited {code} and ran no test", file=sys.stderr)
        raise SystemExit(code or 1)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    print(table(cpu, wall, rows, a.top))
    raise SystemExit(code)


if __name__ == "__main__":
    main()
