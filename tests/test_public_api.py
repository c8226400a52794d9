"""The public API of ``fleet_emu``: exactly what ``__all__`` lists, each name importable, and a run from Python
as a notebook would do it (after httpx's tests/test_exported_members.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import fleet_emu as fe

EXPORTED = {
    "__version__", "Scenario", "RadioConfig", "run", "Result", "Fleet", "load_recording", "Allocator", "Allocation",
    "AllocStatus", "Problem", "make_allocator", "FleetError", "ConfigError", "MapError", "DecodeError",
    "ReportError", "RunError", "SCHEMA_VERSION",
}


def test_all_lists_exactly_the_public_names_and_each_resolves() -> None:
    assert set(fe.__all__) == EXPORTED and len(fe.__all__) == len(EXPORTED)
    for name in fe.__all__:
        assert getattr(fe, name) is not None, name
    assert set(fe.__all__) <= set(dir(fe))
    with pytest.raises(AttributeError):
        fe.no_such_name  # noqa: B018
    for error in ("ConfigError", "MapError", "DecodeError", "ReportError", "RunError"):
        assert issubclass(getattr(fe, error), fe.FleetError)


def test_importing_the_package_loads_no_engine() -> None:
    """A robot process imports fleet_emu first: the public API must not drag the launcher, zenoh or numba in."""
    code = "import sys, fleet_emu; print(sorted(m for m in sys.modules if m.split('.')[0] in " \
           "('zenoh', 'numba', 'scipy', 'rich', 'matplotlib') or m.startswith('fleet_emu.')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_cli_s_parser_loads_no_bus_and_no_arrays() -> None:
    """Every ``fleet`` command builds the whole parser first (``--help``, a refused flag, a listing): built from
    the settings' declarations, it must not load Zenoh, numpy or the codec, which cost a start-up its time."""
    code = "import sys; from fleet_emu.cli import build_parser; build_parser(); print(sorted(m for m in " \
           "sys.modules if m.split('.')[0] in ('zenoh', 'numpy', 'numba', 'msgspec', 'matplotlib') or m in " \
           "('fleet_emu.core.codec', 'fleet_emu.core.node', 'fleet_emu.core.messages')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_scenario_api_loads_overrides_and_rejects() -> None:
    s = fe.Scenario.from_dict({"robots": 2, "map": "hall", "radio": {"comm": "disk", "loss": 0.2}})
    assert (s.robots, s.map, s.radio.comm, s.radio.loss) == (2, "hall", "disk", 0.2)
    t = s.override(allocator="greedy", loss=0.0)
    assert (t.allocator, t.radio.loss, t.radio.comm, s.radio.loss) == ({"type": "greedy"}, 0.0, "disk", 0.2)
    assert fe.Scenario.from_dict(t.to_dict()) == t
    with pytest.raises(fe.ConfigError, match="robots"):
        s.override(robots=-1)
    with pytest.raises(fe.ConfigError, match="speed"):
        s.override(speed=3)


def test_run_from_python_keeps_files_only_where_asked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    s = fe.Scenario().override(robots=2, max_ticks=40, allocator="nearest", seed=2)
    quiet = fe.run(s, in_process=True)
    assert list(tmp_path.iterdir()) == [] and quiet.out_dir is None  # nothing written anywhere asked
    assert quiet.ticks == 40 and not quiet.completed and quiet["recording"]["path"] is None
    ticks, coverage = quiet.coverage_curve()
    assert ticks[-1] == quiet.ticks and coverage[-1] == pytest.approx(quiet.coverage, abs=1e-6)
    assert (coverage[1:] >= coverage[:-1]).all() and coverage[0] > 0
    kept = fe.run(s, tmp_path / "kept", in_process=True)
    assert json.loads((tmp_path / "kept" / "result.json").read_text())["ticks"] == quiet.ticks == kept.ticks
    assert {p.name for p in (tmp_path / "kept").iterdir()} >= {"result.json", "run.mcap", "scenario.json"}
    assert kept["schema_version"] == fe.SCHEMA_VERSION and kept["fleet_emu"] == fe.__version__
    assert kept["coverage"] == quiet["coverage"] and kept["path_length"] == quiet["path_length"]
    with pytest.raises(fe.ConfigError, match="out"):
        fe.run(s, record=True)


def test_fleet_in_memory_from_python(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``fe.Fleet`` and ``fe.run(engine="memory")``: the same run as over Zenoh, in this process."""
    monkeypatch.chdir(tmp_path)
    s = fe.Scenario().override(robots=2, max_ticks=40, allocator="nearest", seed=2)
    env = fe.Fleet(s)
    obs, _ = env.reset(seed=2)
    assert sorted(obs) == env.agents == ["r0", "r1"]
    stepped = env.run()
    direct = fe.run(s, engine="memory")
    assert list(tmp_path.iterdir()) == [] and direct.out_dir is None
    assert stepped["path_length"] == direct["path_length"] and stepped.curve == direct.curve
    assert direct["engine"] == "memory" and direct.ticks == 40
    kept = fe.run(s, tmp_path / "kept", engine="memory")
    assert {p.name for p in (tmp_path / "kept").iterdir()} >= {"result.json", "run.mcap", "scenario.json"}
    assert fe.load_recording(tmp_path / "kept").result["path_length"] == kept["path_length"]
    with pytest.raises(fe.ConfigError, match="engine"):
        fe.run(s, engine="memory", in_process=True)


def test_run_takes_the_cli_s_bus_options_and_refuses_them_where_they_mean_nothing(tmp_path: Path) -> None:
    """``fe.run`` has ``fleet run``'s router options; the memory engine, which has no bus, refuses them and a
    scenario's ``[hosts]`` (it would run every robot here and say nothing); a users file without ``connect``
    (nor hosts) is refused as the CLI refuses it, before anything starts."""
    s = fe.Scenario().override(robots=2, max_ticks=5, allocator="nearest")
    hosted = fe.Scenario.from_dict(s.to_dict() | {"hosts": {"count": 1}})
    assert hosted.hosts is not None and hosted.hosts.count == 1
    with pytest.raises(fe.ConfigError, match=r"memory engine .* no \[hosts\] \(the scenario's; hosts=0"):
        fe.run(hosted, engine="memory")
    with pytest.raises(fe.ConfigError, match=r"memory engine .* no listen"):
        fe.run(s, engine="memory", listen="tcp/127.0.0.1:0")
    with pytest.raises(fe.ConfigError, match=r"^realtime_hz needs the processes engine: the memory engine is "
                                             r"lockstep only$"):
        fe.run(hosted, engine="memory", realtime_hz=10.0)  # real time is refused before the options
    users = tmp_path / "users.txt"
    users.write_text("launcher:x\n")
    with pytest.raises(fe.ConfigError, match="go with --connect"):
        fe.run(s, tmp_path / "out", credentials=users)
    assert not (tmp_path / "out").exists()
    with pytest.raises(fe.ConfigError, match=r"memory engine .* no credentials"):
        fe.run(s, engine="memory", credentials=users)
    done = fe.run(s, listen="tcp/127.0.0.1:0", in_process=True)  # an explicit endpoint reaches the router
    assert done.ticks == 5
