"""``.typecheck/fleet_emu`` (pyproject ``[tool.mypy]``) lays the sources out as they install, for mypy: it must
name every package of ``[tool.setuptools.package-dir]`` and every module of the ``fleet_emu`` façade, each a
relative symlink to its folder or file, and nothing else. A package or façade module added without its link
would go unchecked."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TREE = ROOT / ".typecheck" / "fleet_emu"


def test_the_typecheck_tree_mirrors_the_installed_layout() -> None:
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    top = {name.split(".")[1]: folder for name, folder in setuptools["package-dir"].items() if name.count(".") == 1}
    facade = {p.name for p in (ROOT / setuptools["package-dir"]["fleet_emu"]).glob("*.py")}
    want = {**{name: ROOT / folder for name, folder in top.items()},
            **{name: ROOT / "fleet_emu" / name for name in facade}}
    got = {p.name: p for p in TREE.iterdir() if p.name != "__pycache__"}
    assert set(got) == set(want), "make a relative symlink in .typecheck/fleet_emu for each package and module"
    for name, link in got.items():
        assert link.is_symlink() and not os.path.isabs(os.readlink(link)), f"{link} is not a relative symlink"
        assert link.resolve() == want[name].resolve(), f"{link} points at {link.resolve()}, not {want[name]}"
    packages = {p for p in setuptools["packages"] if p.count(".") >= 1}
    assert {p.split(".")[1] for p in packages} == set(top), "a package inside another folder than its parent's"
