"""Fixtures of the report and Foxglove tests: one short real run on a small map, shared by the session."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.integration.conftest import fleet, result, small_map  # noqa: F401 (small_map is a fixture)


@pytest.fixture(scope="session")
def small_run(small_map: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:  # noqa: F811
    """A finished 3-robot run (run.mcap, result.json) on the two-room map; about 5 s."""
    out = tmp_path_factory.mktemp("run") / "small"
    fleet("run", "--map", str(small_map), "--robots", "3", "--quiet", "--grid-every", "5", "--out", str(out),
          timeout=120)
    assert (out / "run.mcap").is_file() and (out / "result.json").is_file()
    return out
