"""The structure of the product's code: the layout (each subpackage of ``fleet_emu`` a relative link to its root
folder), the layering of its packages, and one builder for each message both engines send.

The layering (``core`` at the bottom; ``world``, ``netem`` and ``agents`` side by side on it, never importing one
another; ``recording``, then ``launch``, then ``sweep`` and the optional ``rl`` and ``ros2`` above) is
import-linter's contract in ``pyproject.toml``, run here; every import counts (inside functions and under
``TYPE_CHECKING``). What import-linter cannot express, that only the ``fleet_emu`` package itself (the façade
``fleet_emu/__init__.py`` and the CLI ``fleet_emu/cli.py``) sits on top, is checked by walking the imports here.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "world", "netem", "agents", "recording", "launch", "sweep", "fleet_emu")


def test_each_subpackage_is_a_relative_link_to_its_root_folder() -> None:
    """``fleet_emu/<name>`` is a relative symlink to ``../<name>`` for every subpackage pyproject lists (or a real
    folder of ``fleet_emu/``), so a broken or absolute link fails here rather than in an install."""
    listed = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    top = sorted({p.split(".")[1] for p in listed if p.count(".") >= 1})
    assert top, "pyproject lists no subpackage"
    for name in top:
        link = ROOT / "fleet_emu" / name
        if link.is_symlink():
            assert os.readlink(link) == f"../{name}", f"{link} should link to ../{name}, not {os.readlink(link)}"
            assert (ROOT / name).is_dir() and not (ROOT / name).is_symlink(), f"{name}/ is not a real folder"
        assert (link / "__init__.py").is_file(), f"{link} does not reach a package (broken link?)"
    linked = {p.name for p in (ROOT / "fleet_emu").iterdir() if p.is_symlink()}
    assert linked == set(top), f"links in fleet_emu/ without a package in pyproject (or the reverse): {linked}"


def _lint_imports(cwd: Path, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``lint-imports`` (import-linter's command) in ``cwd``, without its cache."""
    return subprocess.run([sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command;"
                           " sys.exit(lint_imports_command())", "--no-cache", *args],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


def test_the_layering_contract_is_kept() -> None:
    run = _lint_imports(ROOT)
    assert run.returncode == 0 and "0 broken" in run.stdout, run.stdout + run.stderr


def test_the_contract_sees_function_local_and_type_checking_imports(tmp_path: Path) -> None:
    """The tool is not blind: in a copy of the contract over a probe package, an import inside a function and one
    under ``TYPE_CHECKING`` that go against the layers each break it."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    layers = config["contracts"][0]["layers"]
    pkg = tmp_path / "fleet_emu"
    for name in ("core", "world", "netem", "agents", "recording", "launch", "sweep"):
        (pkg / name).mkdir(parents=True)
        (pkg / name / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "netem" / "probe.py").write_text("def f():\n    from fleet_emu.world import x\n")
    (pkg / "core" / "probe.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from fleet_emu.launch import y\n")
    contract = "\n".join(f'  "{layer}",' for layer in layers)
    (tmp_path / ".importlinter.toml").write_text(
        '[tool.importlinter]\nroot_package = "fleet_emu"\nexclude_type_checking_imports = false\n'
        f'[[tool.importlinter.contracts]]\nname = "layers"\ntype = "layers"\nlayers = [\n{contract}\n]\n')
    run = _lint_imports(tmp_path, "--config", ".importlinter.toml", env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert run.returncode == 1, run.stdout + run.stderr
    assert "fleet_emu.netem.probe -> fleet_emu.world" in run.stdout, run.stdout
    assert "fleet_emu.core.probe -> fleet_emu.launch" in run.stdout, run.stdout


def module_name(path: Path, root: Path = ROOT) -> str:
    """``world/sim.py`` -> ``fleet_emu.world.sim``, ``fleet_emu/cli.py`` -> ``fleet_emu.cli`` (each root folder is
    ``fleet_emu/<folder>``), a package's ``__init__.py`` -> the package."""
    rel = path.relative_to(root).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts if parts[0] == "fleet_emu" else ["fleet_emu", *parts])


def imports(path: Path, root: Path = ROOT) -> Iterator[tuple[int, str]]:
    """Every product or third-party module an import statement of ``path`` names, with its line (relative
    imports resolved; ``from fleet_emu import cli`` names ``fleet_emu.cli``, ``from fleet_emu import
    __version__`` the façade ``fleet_emu``)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join([*parts[: len(parts) - node.level + 1], *([base] if base else [])])
            if base != "fleet_emu":
                yield node.lineno, base
                continue
            for alias in node.names:
                sub = alias.name in PACKAGES[:-1] or alias.name == "cli"
                yield node.lineno, f"fleet_emu.{alias.name}" if sub else "fleet_emu"


def product_files(root: Path = ROOT) -> list[Path]:
    return [path for pkg in PACKAGES[:-1] for path in sorted((root / pkg).rglob("*.py"))]


def facade_imports(root: Path = ROOT) -> list[str]:
    """Every import of the façade or the CLI (``fleet_emu``, ``fleet_emu.cli``) from a subpackage."""
    found = []
    for path in product_files(root):
        for line, target in imports(path, root):
            if target in ("fleet_emu", "fleet_emu.cli") or target.startswith("fleet_emu.cli."):
                found.append(f"{path.relative_to(root)}:{line}: imports {target}")
    return sorted(set(found))


def test_no_subpackage_imports_the_facade_or_the_cli() -> None:
    bad = facade_imports()
    assert not bad, "the façade and the CLI sit on top:\n" + "\n".join(bad)


def test_the_facade_check_sees_function_local_and_relative_imports(tmp_path: Path) -> None:
    (tmp_path / "recording").mkdir()
    (tmp_path / "recording" / "probe.py").write_text(
        "def f():\n    from fleet_emu import __version__\n    from .. import cli\n")
    assert facade_imports(tmp_path) == ["recording/probe.py:2: imports fleet_emu",
                                        "recording/probe.py:3: imports fleet_emu.cli"]


#: Where each message both engines send is built (``tests/integration/test_engine_messages.py`` compares the
#: two engines' messages): one builder, called by the node shell and by the memory engine alike, so that a
#: field cannot be filled in one engine and forgotten in the other. ``Command``: the brain's decision, and in
#: real time (the processes engine only) a step along the last plan; ``Stop``: the world's end, and the stops
#: only processes have (the world's start-up timeout, the launcher's Ctrl-C).
BUILT_IN: dict[str, frozenset[str]] = {
    "Hello": frozenset({"world/messages.py"}),
    "Ready": frozenset({"core/control_messages.py"}),
    "Observation": frozenset({"world/messages.py"}),
    "WorldState": frozenset({"world/messages.py"}),
    "Links": frozenset({"netem/channel.py"}),
    "RxBundle": frozenset({"netem/channel.py"}),
    "TxBundle": frozenset({"agents/outputs.py"}),
    "BeliefSnapshot": frozenset({"agents/outputs.py"}),
    "RobotReport": frozenset({"agents/outputs.py"}),
    "BaseReport": frozenset({"agents/outputs.py"}),
    "Command": frozenset({"agents/brain.py", "agents/realtime.py"}),
    "Stop": frozenset({"world/messages.py", "world/node.py", "launch/runner.py"}),
}


def constructions(root: Path = ROOT) -> dict[str, set[str]]:
    """The product files that call each message class of :data:`BUILT_IN` (``Name(...)`` or ``x.Name(...)``)."""
    found: dict[str, set[str]] = {name: set() for name in BUILT_IN}
    for path in product_files(root):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
                if name in found:
                    found[name].add(str(path.relative_to(root)))
    return found


def test_each_lockstep_message_is_built_in_one_place() -> None:
    built = constructions()
    wrong = {name: sorted(files) for name, files in built.items() if files != BUILT_IN[name]}
    assert not wrong, f"messages built elsewhere than their one builder (expected {BUILT_IN}): {wrong}"


def _is_test_module(name: str) -> bool:
    """``tests.conftest``, ``tests.sweep.conftest``, ``tests.core.test_keys``: a module pytest loads itself."""
    last = name.rpartition(".")[2]
    return last == "conftest" or last.startswith("test_")


def imports_of_test_modules(root: Path = ROOT) -> list[str]:
    """Every import, in ``tests/`` and ``benchmarks/``, of a conftest or of a test module (``test_*``), relative
    and function-local ones included: shared helpers live in ``tests/harness/`` or in fixtures."""
    found = []
    for path in sorted([*(root / "tests").rglob("*.py"), *(root / "benchmarks").rglob("*.py")]):
        rel = path.relative_to(root)
        package = ".".join(rel.parent.parts)
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    base = ".".join([*parts[: len(parts) - node.level + 1], *([base] if base else [])])
                targets = [base, *(f"{base}.{a.name}" for a in node.names)]
            else:
                continue
            found += [f"{rel}:{node.lineno}: imports {t}" for t in targets if _is_test_module(t)]
    return sorted(set(found))


def test_no_module_imports_a_conftest_or_a_test_module() -> None:
    bad = imports_of_test_modules()
    assert not bad, "import shared helpers from tests/harness/ (or use a fixture):\n" + "\n".join(bad)


def test_the_test_import_check_sees_function_local_and_relative_imports(tmp_path: Path) -> None:
    (tmp_path / "tests" / "sweep").mkdir(parents=True)
    (tmp_path / "tests" / "sweep" / "test_probe.py").write_text(
        "from tests.harness.cli import run_cli\nimport tests.conftest\n"
        "def f():\n    from .test_report import row\n    from tests.sweep import conftest\n")
    assert imports_of_test_modules(tmp_path) == ["tests/sweep/test_probe.py:2: imports tests.conftest",
                                             "tests/sweep/test_probe.py:4: imports tests.sweep.test_report",
                                             "tests/sweep/test_probe.py:5: imports tests.sweep.conftest"]
