"""The structure of the product's code: the layering of its packages (README "Code layout"), checked on every
import statement, and one builder for each message both engines send.

``core`` is at the bottom; ``world``, ``netem`` and ``agents`` sit side by side on it and never import one
another; ``recording`` and ``launch`` sit above them (``recording`` never imports ``launch``), ``sweep`` above
``launch``; only the ``fleet_emu`` package itself (the façade ``fleet_emu/__init__.py`` and the CLI
``fleet_emu/cli.py``) sits on top. Every import counts: at module level, inside functions, and under
``TYPE_CHECKING`` (a dependency a type checker sees is still a dependency).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "world", "netem", "agents", "recording", "launch", "sweep", "fleet_emu")
TOP = "top"  # the fleet_emu package: the façade and the CLI

#: What each layer may import, besides itself and third-party code.
ALLOWED: dict[str, frozenset[str]] = {
    "core": frozenset(),
    "world": frozenset({"core"}),
    "netem": frozenset({"core"}),
    "agents": frozenset({"core"}),
    "recording": frozenset({"core", "world", "netem", "agents"}),
    "launch": frozenset({"core", "world", "netem", "agents", "recording"}),
    "sweep": frozenset({"core", "world", "netem", "agents", "recording", "launch"}),
    TOP: frozenset({"core", "world", "netem", "agents", "recording", "launch", "sweep"}),
}


def layer_of(module: str) -> str | None:
    """The layer of an absolute module name (``fleet_emu.world.sim`` -> ``world``, ``fleet_emu`` and
    ``fleet_emu.cli`` -> top); None for code outside the product."""
    parts = module.split(".")
    if parts[0] != "fleet_emu":
        return None
    if len(parts) > 1 and parts[1] in PACKAGES[:-1]:
        return parts[1]
    return TOP


def module_name(path: Path, root: Path = ROOT) -> str:
    """``world/sim.py`` -> ``fleet_emu.world.sim``, ``fleet_emu/cli.py`` -> ``fleet_emu.cli`` (the pyproject
    package-dir mapping), a package's ``__init__.py`` -> the package."""
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
    return [path for pkg in PACKAGES for path in sorted((root / pkg).rglob("*.py"))]


def violations(root: Path = ROOT) -> list[str]:
    """Every import against :data:`ALLOWED`, as ``path:line: layer imports module (its layer)``."""
    found = []
    for path in product_files(root):
        mine = layer_of(module_name(path, root))
        assert mine is not None
        for line, target in imports(path, root):
            theirs = layer_of(target)
            if theirs is None or theirs == mine:
                continue
            if theirs not in ALLOWED[mine]:
                found.append(f"{path.relative_to(root)}:{line}: {mine} imports {target} ({theirs})")
    return sorted(set(found))


def test_no_import_goes_against_the_layering() -> None:
    bad = violations()
    assert not bad, "imports against the layering:\n" + "\n".join(bad)


def test_the_check_sees_function_local_relative_and_facade_imports(tmp_path: Path) -> None:
    """The walker is not blind: a function-local import, a relative one and one of the façade are each seen,
    resolved and reported with their file and line."""
    (tmp_path / "netem").mkdir()
    (tmp_path / "recording").mkdir()
    (tmp_path / "netem" / "probe.py").write_text(
        "import numpy\n\n\ndef f():\n    from fleet_emu.world.sim import World\n    from ..agents import brain\n")
    (tmp_path / "recording" / "probe.py").write_text(
        "from fleet_emu import __version__\nfrom fleet_emu.launch.progress import radio_label\n")
    assert (6, "fleet_emu.agents") in list(imports(tmp_path / "netem" / "probe.py", tmp_path))
    assert violations(tmp_path) == [
        "netem/probe.py:5: netem imports fleet_emu.world.sim (world)",
        "netem/probe.py:6: netem imports fleet_emu.agents (agents)",
        "recording/probe.py:1: recording imports fleet_emu (top)",
        "recording/probe.py:2: recording imports fleet_emu.launch.progress (launch)",
    ]


#: Where each message both engines send is built (``tests/integration/test_engine_messages.py`` compares the
#: two engines' messages): one builder, called by the node shell and by the memory engine alike, so that a
#: field cannot be filled in one engine and forgotten in the other. ``Command``: the brain's decision, and in
#: real time (the processes engine only) a step along the last plan; ``Stop``: the world's end, and the stops
#: only processes have (the world's start-up timeout, the launcher's Ctrl-C).
BUILT_IN: dict[str, frozenset[str]] = {
    "Hello": frozenset({"world/messages.py"}),
    "Ready": frozenset({"core/lobby.py"}),
    "Observation": frozenset({"world/messages.py"}),
    "WorldState": frozenset({"world/messages.py"}),
    "Links": frozenset({"netem/channel.py"}),
    "RxBundle": frozenset({"netem/channel.py"}),
    "TxBundle": frozenset({"agents/outputs.py"}),
    "BeliefSnapshot": frozenset({"agents/outputs.py"}),
    "AgentReport": frozenset({"agents/outputs.py"}),
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
