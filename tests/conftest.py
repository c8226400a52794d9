"""What the whole suite shares as fixtures and hooks: the drawn maps, the one finished run that several tests only
read, the compiled kernels and the children's bytecode cache. Helper functions live in ``tests/harness/`` (the
CLI, the processes, the files a test makes); test modules import them from there, never from this module or
from one another (``tests/test_layering.py`` checks it)."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

pytest.register_assert_rewrite("tests.harness")

from tests.harness.cli import run_cli  # noqa: E402  (after the assertion rewrite is registered)
from tests.harness.files import TWO_ROOMS, draw_map  # noqa: E402


def pytest_configure(config: pytest.Config) -> None:
    """The suite starts a few hundred interpreters (fleets, CLIs, fork servers). They all load the kernels from the
    user's kernel cache, also those whose test gives them a user cache of their own (``XDG_CACHE_HOME``, for maps):
    ``FLEET_KERNEL_CACHE`` is set to it. Where ``PYTHONDONTWRITEBYTECODE`` keeps bytecode out of the tree, each
    would also compile the package from source again (about 0.2 CPU s): they share one bytecode cache in a folder
    of the session's instead (``PYTHONPYCACHEPREFIX``), and the tree stays as clean as the variable asks."""
    from fleet_emu.core.jit import cache_dir

    os.environ.setdefault("FLEET_KERNEL_CACHE", str(cache_dir()))
    if not os.environ.get("PYTHONDONTWRITEBYTECODE") or os.environ.get("PYTHONPYCACHEPREFIX"):
        return
    prefix = tempfile.mkdtemp(prefix="fleet-tests-pycache-")
    del os.environ["PYTHONDONTWRITEBYTECODE"]
    os.environ["PYTHONPYCACHEPREFIX"] = prefix
    config.add_cleanup(lambda: shutil.rmtree(prefix, ignore_errors=True))
    config.stash[_PYCACHE] = Path(prefix)


_PYCACHE = pytest.StashKey[Path]()
OWN = {"fleet_emu", "tests", "benchmarks"}  # the repository's modules: compiled by the children themselves


def _share_installed_bytecode(prefix: Path) -> int:
    """Link the installed bytecode of every module this process imported (the standard library, numpy, numba,
    zenoh...) into the children's bytecode cache, where each would otherwise be compiled from source once more
    (about 4 CPU s for the first interpreter that loads the kernels). The package's own modules are left to the
    children: this process wrote none. Returns how many were linked."""
    linked = 0
    for name, module in list(sys.modules.items()):
        cached, source = getattr(module, "__cached__", None), getattr(module, "__file__", None)
        if name.partition(".")[0] in OWN or not cached or not source or not os.path.isfile(cached):
            continue
        target = prefix / os.path.dirname(os.path.abspath(source)).lstrip(os.sep) / os.path.basename(cached)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            target.symlink_to(cached)
            linked += 1
        except OSError:
            pass
    return linked


@pytest.fixture(scope="session", autouse=True)
def _compiled_kernels(request: pytest.FixtureRequest) -> None:
    """Compile (or load) the numba kernels once, before any test: in a fresh checkout the cache is empty, and
    the first fleet's world, netem and fork server would each compile every kernel at once (three times the
    work of one compile); after this they all load the cached machine code. Then the children's bytecode
    cache, if this session made one, gets what this process has imported by then (a launcher's too)."""
    from fleet_emu.core.kernels import warm_up

    warm_up()
    prefix = request.config.stash.get(_PYCACHE, None)
    if prefix is not None:
        import fleet_emu.launch.runner  # (what a launcher imports besides the kernels)
        import fleet_emu.recording.live  # noqa: F401

        _share_installed_bytecode(prefix)


@pytest.fixture(scope="session")
def small_bitmap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """:data:`TWO_ROOMS` as ``two_rooms.png`` alone: a bare bitmap, read one pixel per cell at the cell size a
    run gives (the benchmarks that fit a map to a number of cells give theirs)."""
    return draw_map(TWO_ROOMS, tmp_path_factory.mktemp("maps") / "two_rooms.png")


@pytest.fixture(scope="session")
def small_map(small_bitmap: Path) -> Path:
    """``two_rooms.yaml``: the bitmap with its scale, 0.5 m per pixel (12 x 24 cells at the default cell size),
    so that a run needs no --cell-size."""
    path = small_bitmap.with_suffix(".yaml")
    path.write_text(f"image: {small_bitmap.name}\nresolution: 0.5\norigin: [0.0, 0.0, 0.0]\n")
    return path


@pytest.fixture(scope="session")
def small_run(small_map: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The suite's one plain finished run over processes, which tests only read: three robots on the two-room
    map (the default scenario otherwise: seed 0, 10 % loss, forked robots), recorded with the grid every 5
    ticks; ``run.mcap``, ``result.json`` and the logs in the returned directory."""
    out = tmp_path_factory.mktemp("run") / "small"
    run_cli(["run", "--map", str(small_map), "--robots", "3", "--quiet", "--grid-every", "5", "--out", str(out)],
            check=True)
    assert (out / "run.mcap").is_file() and (out / "result.json").is_file()
    return out
