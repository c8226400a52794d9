"""Hostile and careless input: each is refused with one line and exit 2 before anything large is allocated
(``tracemalloc`` sees numpy's arrays: the peak stays small) or any file is written."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from fleet_emu.core.access import read_users
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.limits import MAX_NESTING, nesting
from tests.harness.cli import run_cli

BUDGET = {"FLEET_MEM_AVAILABLE_MB": "4000"}  # a 4 GB machine, whatever this one has
PEAK_MB = 64  # far below any of the refused grids (1 to 2.4 G cells)


@pytest.fixture(scope="module", autouse=True)
def _imported(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The run path's modules imported before tracemalloc watches (it makes imports slow, and they are not the
    allocations under test)."""
    yaml = _yaml(_floor(tmp_path_factory.mktemp("warm")), "0.5")
    assert run_cli(["run", "--map", str(yaml), "--robots", "0"])[0] == 2


def _refused(argv: list[str], tmp_path: Path, env: dict[str, str] | None = None) -> str:
    """``fleet ARGV`` in process: exit 2, one ``fleet: error:`` line, a small allocation peak, no --out folder;
    the line."""
    out = tmp_path / "out"
    tracemalloc.start()
    try:
        code, _, err = run_cli([*argv, "--out", str(out)], env={**BUDGET, **(env or {})})
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("fleet: error: "), err[-2000:]
    assert peak < PEAK_MB * 2**20, f"{peak / 2**20:.0f} MB allocated before the refusal"
    assert not out.exists()
    return lines[0]


def _floor(folder: Path) -> Path:
    """A 300 x 200 px white floor."""
    path = folder / "floor.png"
    Image.fromarray(np.full((200, 300), 255, np.uint8)).save(path)
    return path


@pytest.fixture
def image(tmp_path: Path) -> Path:
    return _floor(tmp_path)


def _yaml(image: Path, resolution: str) -> Path:
    path = image.with_name(f"floor-{len(resolution)}.yaml")
    path.write_text(f"image: {image.name}\nresolution: {resolution}\n")
    return path


def test_a_map_too_large_for_the_memory_is_refused_before_its_grid_is_built(image: Path, tmp_path: Path) -> None:
    line = _refused(["run", "--engine", "memory", "--map", "office", "--cell-size", "0.001"], tmp_path)
    assert line.startswith("fleet: error: map office (25002 x 40002 cells) with 4 robots needs about ")
    assert line.endswith("use larger cells (--cell-size) or a smaller map")
    line = _refused(["run", "--map", str(_yaml(image, "100.0"))], tmp_path)  # 200 x 300 px of 100 m, and a border
    assert "(40002 x 60002 cells)" in line and "3.9 GB is available" in line


@pytest.mark.parametrize("value", [".inf", "1.0e+300", ".nan", "-1.0"])
def test_a_map_yaml_resolution_must_be_finite_and_in_range(image: Path, tmp_path: Path, value: str) -> None:
    line = _refused(["run", "--engine", "memory", "--map", str(_yaml(image, value))], tmp_path)
    assert "'resolution' must be a finite number in [1e-09, 1000]" in line


def test_a_map_yaml_origin_must_be_finite(image: Path, tmp_path: Path) -> None:
    path = _yaml(image, "0.5")
    path.write_text(path.read_text() + "origin: [0.0, .inf, 0.0]\n")
    assert "'origin' must be three finite numbers" in _refused(["run", "--map", str(path)], tmp_path)


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_deeply_nested_scenario_is_one_line(tmp_path: Path, suffix: str) -> None:
    deep = "[" * 3000 + "]" * 3000
    path = tmp_path / f"deep{suffix}"
    path.write_text(f"name = {deep}\n" if suffix == ".toml" else f'{{"name": {deep}}}')
    line = _refused(["run", "--scenario", str(path)], tmp_path)
    assert line.endswith(f"levels of brackets deep, more than the {MAX_NESTING} allowed")


def test_nesting_is_counted_outside_strings_and_comments() -> None:
    assert nesting('a = [[1], {b = "[[[[[["}] # [[[[[[\nc = \'[[[[\'\nd = """\n[[[[\n"""') == 2
    assert nesting(json.dumps({"a": [[["x]]]]["]]]})) == 4
    assert nesting("[" * 100_000) == 100_000  # linear, no recursion


def test_a_huge_scenario_or_name_is_refused_before_it_is_copied(tmp_path: Path) -> None:
    big = tmp_path / "big.toml"
    big.write_text('name = "' + "x" * 2_000_000 + '"\n')
    assert _refused(["run", "--scenario", str(big)], tmp_path).endswith("more than the 1048576 a scenario may have")
    long = tmp_path / "long.toml"
    long.write_text('name = "' + "x" * 5000 + '"\n')
    assert _refused(["run", "--scenario", str(long)], tmp_path) == \
        f"fleet: error: scenario {long}: name is 5000 characters long, more than the 200 allowed"
    path = tmp_path / "alloc.toml"
    path.write_text('[allocator]\ntype = "nearest"\nnote = "' + "y" * 5000 + '"\n')
    assert "holds a string of 5000 characters, more than the 4096 allowed" in \
        _refused(["run", "--scenario", str(path)], tmp_path)


def _users(tmp_path: Path, mode: int) -> Path:
    path = tmp_path / f"users-{mode:o}.txt"
    path.write_text("launcher:secret\nhost0:secret\n")
    path.chmod(mode)
    return path


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o620])
def test_a_users_file_others_may_read_or_write_is_refused_as_ssh_does(tmp_path: Path, mode: int) -> None:
    users = _users(tmp_path, mode)
    want = (f"fleet: error: --credentials {users} is open to its group or others (mode 0{mode:o}): its passwords "
            f"must be yours alone; chmod 600 {users}")
    assert _refused(["run", "--connect", "tcp/127.0.0.1:9", "--credentials", str(users)], tmp_path) == want
    assert _refused(["run", "--hosts", "1", "--credentials", str(users)], tmp_path) == want
    code, _, err = run_cli(["host", "--connect", "tcp/127.0.0.1:9", "--credentials", str(users), "--once"])
    assert code == 2 and err.strip() == want
    code, _, err = run_cli(["router-config", "--robots", "2", "--users", str(users)])
    assert code == 2 and err.strip() == want.replace("--credentials", "--users")
    assert users.read_text() == "launcher:secret\nhost0:secret\n"  # router-config left it as it was


def test_a_users_file_of_mode_600_is_read(tmp_path: Path) -> None:
    assert read_users(_users(tmp_path, 0o600)) == {"launcher": "secret", "host0": "secret"}
    with pytest.raises(ConfigError, match="cannot read it"):
        read_users(tmp_path / "absent.txt")


def test_a_negative_base_cell_names_its_flag() -> None:
    code, _, err = run_cli(["run", "--engine", "memory", "--base-cell=-1,2"])
    assert code == 2 and err.count("\n") == 1, err
    assert "argument --base-cell: expected ROW,COL, each a whole number >= 0, got '-1,2'" in err, err
