"""The project installed for real (not editable) into a fresh virtual environment, and used as a user would:
from a neutral directory, beside packages that own the bare names ``launch``, ``core`` and ``agents`` (ROS 2,
openai-agents), and with an allocator plugin installed from a package outside this repository."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.harness.cli import ROOT

# Regular packages named like the clashing ones; importing any of them fails loudly.
SHADOW = 'raise ImportError("this {name!r} is another project\'s package, not fleet-emu\'s")\n'

PLUGIN_PYPROJECT = """\
[build-system]
requires = ["setuptools>=68"]
build-backend = "setuptools.build_meta"

[project]
name = "largest-alloc"
version = "0.1.0"

[project.entry-points."fleet_emu.allocators"]
largest = "largest_alloc:Largest"

[tool.setuptools]
py-modules = ["largest_alloc"]
"""

PLUGIN_MODULE = '''\
"""An allocator from outside fleet-emu: the reachable frontier cluster of most cells, less its path cost."""

from fleet_emu.agents.allocators import Allocation, Allocator, Param


class Largest(Allocator, plugin_name="largest"):
    """Score = cluster size - ``cost_weight`` * wavefront cost; the best reachable score wins (ties: lower index)."""

    parameters = {"cost_weight": Param(0.1, ge=0)}

    def allocate(self, problem, inbox=()):
        me = problem.poses[problem.me]
        scores = [(c.size - self.cost_weight * wf[me], -j) for j, (c, wf) in
                  enumerate(zip(problem.clusters, problem.wavefronts)) if wf[me] >= 0]
        return Allocation.assigned(problem, -max(scores)[1]) if scores else Allocation.none()
'''


@dataclasses.dataclass(frozen=True)
class Venv:
    path: Path
    home: Path  # an empty working directory: nothing importable from the cwd

    @property
    def site_packages(self) -> Path:
        return self.path / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"

    def run(self, *args: str, pythonpath: Path | None = None, timeout: float = 120) -> subprocess.CompletedProcess[str]:
        """A command of the venv's ``bin/`` (``python``, ``pip``, ``fleet``), run from :attr:`home`."""
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        if pythonpath is not None:
            env["PYTHONPATH"] = str(pythonpath)
        return subprocess.run([str(self.path / "bin" / args[0]), *args[1:]], capture_output=True, text=True,
                              cwd=self.home, env=env, timeout=timeout)


@pytest.fixture(scope="session")
def venv(tmp_path_factory: pytest.TempPathFactory) -> Venv:
    """A fresh venv (numpy, numba and zenoh from the system site-packages) with this repository installed
    non-editable, and an ``agents`` package beside it. pip builds in the source tree (``build/``), so what
    is installed is a copy of the working tree: the checkout may be in use by other test runs."""
    root = tmp_path_factory.mktemp("install")
    src = root / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", ".venv", "*.egg-info", "__pycache__", "build", "runs", ".pytest_cache", ".ruff_cache"))
    path = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(path)], check=True, timeout=120)
    home = root / "home"
    home.mkdir()
    venv = Venv(path, home)
    pip = venv.run("pip", "install", "--no-deps", "--quiet", "--disable-pip-version-check", str(src), timeout=300)
    assert pip.returncode == 0, pip.stdout + pip.stderr
    where = venv.run("python", "-c", "import fleet_emu; print(fleet_emu.__file__)")
    assert where.returncode == 0, where.stderr
    module = Path(where.stdout.strip())  # the venv's own copy, not an editable install elsewhere
    assert module == venv.site_packages / "fleet_emu" / "__init__.py", module
    for data in ("py.typed", "world/registry.toml", "launch/scenarios/default.toml", "sweep/studies/bautin-fig5.toml",
                 "sweep/studies/open-512.png"):
        assert (module.parent / data).is_file(), data  # the package data a user's install needs
    (venv.site_packages / "agents").mkdir()
    (venv.site_packages / "agents" / "__init__.py").write_text(SHADOW.format(name="agents"))
    return venv


def _one_process_per_robot(res: dict, robots: int) -> None:
    agents = res["pids"]["robots"]
    assert len(agents) == robots and all(isinstance(p, int) and p > 0 for p in agents)
    assert len({*agents, res["pids"]["world"], res["pids"]["netem"]}) == robots + 2


@pytest.mark.slow
def test_installed_fleet_runs_beside_clashing_packages(venv: Venv, small_map: Path, tmp_path: Path) -> None:
    shadow = tmp_path / "shadow"
    for name in ("launch", "core"):
        (shadow / name).mkdir(parents=True)
        (shadow / name / "__init__.py").write_text(SHADOW.format(name=name))
    for name in ("launch", "core", "agents"):  # the clashing packages are really there
        probe = venv.run("python", "-c", f"import {name}", pythonpath=shadow)
        assert probe.returncode == 1 and "another project's package" in probe.stderr, probe.stderr
    out = tmp_path / "run"
    proc = venv.run("fleet", "run", "--map", str(small_map), "--robots", "2", "--max-ticks", "300", "--quiet",
                    "--out", str(out), pythonpath=shadow)
    print(f"fleet run -> exit {proc.returncode}; stdout: {proc.stdout.strip()}; stderr: {proc.stderr.strip()}")
    assert proc.returncode in (0, 3), proc.stderr
    assert "Traceback" not in proc.stderr
    res = json.loads((out / "result.json").read_text())
    print({k: res[k] for k in ("allocator", "robots", "ticks", "completed", "coverage", "pids")})
    _one_process_per_robot(res, 2)
    assert res["allocator"] == "minpos" and res["failed"] == [] and res["coverage"] > 0.5
    for log in out.glob("*.log"):
        assert "Traceback" not in log.read_text(errors="replace"), log.name


@pytest.mark.slow
def test_an_allocator_plugin_installed_from_outside(venv: Venv, small_map: Path, tmp_path: Path) -> None:
    pkg = tmp_path / "largest-alloc"
    pkg.mkdir()
    (pkg / "pyproject.toml").write_text(PLUGIN_PYPROJECT)
    (pkg / "largest_alloc.py").write_text(PLUGIN_MODULE)
    pip = venv.run("pip", "install", "--no-deps", "--quiet", "--disable-pip-version-check", str(pkg), timeout=300)
    assert pip.returncode == 0, pip.stdout + pip.stderr

    check = venv.run("python", "-c", "from fleet_emu.agents.allocators import allocator_names, make_allocator\n"
                     "from fleet_emu.agents.allocators.conformance import api_test, seed_test\n"
                     "api_test({'type': 'largest'})\nseed_test({'type': 'largest', 'cost_weight': 0.5})\n"
                     "print(allocator_names())\nprint(type(make_allocator({'type': 'largest'})).__module__)")
    assert check.returncode == 0, check.stderr
    names, module = check.stdout.strip().splitlines()
    assert "'largest'" in names and "'minpos'" in names and module == "largest_alloc"
    listing = venv.run("fleet", "allocators")
    line = next(ln for ln in listing.stdout.splitlines() if ln.startswith("largest "))  # its docstring, then
    assert line.endswith("[plugin largest_alloc: cost_weight=0.1 (>= 0)]"), listing.stdout  # where it comes from

    out = tmp_path / "run"
    proc = venv.run("fleet", "run", "--allocator", "largest", "--robots", "3", "--map", str(small_map),
                    "--max-ticks", "400", "--quiet", "--out", str(out))
    print(f"fleet run --allocator largest -> exit {proc.returncode}; {proc.stdout.strip()}")
    assert proc.returncode in (0, 3) and "Traceback" not in proc.stderr, proc.stderr
    res = json.loads((out / "result.json").read_text())
    _one_process_per_robot(res, 3)
    assert res["allocator"] == "largest" and res["failed"] == [] and res["coverage"] > 0.5

    bad = tmp_path / "bad.toml"
    bad.write_text('[allocator]\ntype = "largest"\ncost_weight = -1\n')
    proc = venv.run("fleet", "run", "--scenario", str(bad), "--map", str(small_map), "--quiet",
                    "--out", str(tmp_path / "bad"))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"fleet: error: scenario {bad}: allocator 'largest': cost_weight must be >= 0 (got -1)"], proc.stderr
