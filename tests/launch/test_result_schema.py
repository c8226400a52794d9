"""``result.json`` against its schema (``recording/result.schema.json``, docs/reference/result.md): the runs of
every kind write a file the schema accepts (the memory engine plain, with a base and relaying, interrupted; the
processes engine interrupted before it started here, in real time with a base and relaying and failed where those
runs are made), and the schema refuses what breaks the contract."""

from __future__ import annotations

import json
import re
import signal
from pathlib import Path
from typing import Any

import msgspec
import pytest

import fleet_emu as fe
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import RobotReport
from fleet_emu.core.scenario import Scenario
from fleet_emu.core.version import SCHEMA_VERSION
from fleet_emu.launch import memory, runner
from fleet_emu.launch.memory import Fleet, run_memory
from fleet_emu.launch.recover import recover
from fleet_emu.launch.runner import RunOptions, run_fleet
from fleet_emu.launch.signals import Interrupts
from fleet_emu.recording import recover as recording_recover
from fleet_emu.recording.metrics import DEPRECATED_GROUPS
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.result import (
    RENAMED,
    build_result,
    metrics_schema,
    result_schema,
    validate_metrics,
    validate_result,
)


def _scenario(**kw: Any) -> Scenario:
    return Scenario().override(map="office", robots=3, seed=1, max_ticks=40, **kw)


def _written(out: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / "result.json").read_text())
    validate_result(data)
    return data


def _interrupts() -> Interrupts:
    irq = Interrupts()
    irq._handle(signal.SIGTERM, None)  # as the CLI's handler does on a signal
    return irq


@pytest.fixture(scope="module")
def memory_run() -> dict[str, Any]:
    return dict(Fleet(_scenario()).run().data)


def test_memory_engine_runs_plain_with_a_base_and_relaying_and_interrupted(memory_run: dict[str, Any],
                                                                           tmp_path: Path) -> None:
    validate_result(memory_run)
    assert memory_run["engine"] == "memory" and "base" not in memory_run and "relay" not in memory_run
    based = Fleet(_scenario(base=True, relay="flood", relay_ttl=2)).run().data
    validate_result(based)
    assert based["base"]["ticks"] is not None and set(based["relay"]["kinds"]) >= {"pose", "map"}
    planner = Fleet(_scenario(allocator="mhm", base=True)).run().data  # a base-station planner: tree relaying
    validate_result(planner)
    assert planner["relay"]["policy"] == "tree"
    stopped = run_memory(_scenario(), tmp_path / "irq", record=False, interrupts=_interrupts())
    assert _written(tmp_path / "irq") == stopped.data and stopped["reason"] == "interrupted"


def test_a_processes_run_interrupted_before_it_started(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Interrupted before anything started: no pids; the file is the one builder's, as built. The other processes
    runs' files are checked where those runs are made (every test reads a result through
    ``tests.harness.cli.result``, which validates it): in real time with a base and relaying (``test_realtime.py``),
    failed waiting for its hosts (``test_hosts.py``)."""
    built = _built_by(runner, monkeypatch)
    run_fleet(_scenario(), RunOptions(out_dir=tmp_path / "irq", interrupts=_interrupts()))
    data = _written(tmp_path / "irq")
    assert data["pids"] == {} and data["engine"] == "processes" and data["reason"] == "interrupted"
    assert built == [data]


def _built_by(module: Any, monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Every ``result.json`` that ``module`` has the one builder (``recording/result.build_result``) make, as it
    was made (through JSON, so that a key changed afterwards shows)."""
    built: list[dict[str, Any]] = []

    def spy(*args: Any, **kwargs: Any) -> dict[str, Any]:
        data = build_result(*args, **kwargs)
        built.append(json.loads(json.dumps(data)))
        return data

    monkeypatch.setattr(module, "build_result", spy)
    return built


def test_every_key_of_a_memory_run_and_of_its_recovery_is_the_builders(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The memory engine's ``result.json``, and the one ``fleet recover`` writes when it is lost (the launcher
    killed before it wrote it), are each exactly what the builder made: nothing adds, drops or changes a key
    afterwards; both meet the schema."""
    built = _built_by(memory, monkeypatch)
    run_memory(_scenario(), tmp_path / "run")
    ran = _written(tmp_path / "run")
    assert built == [ran] and ran["reason"] == "max_ticks" and ran["recording"]["messages"] > 0
    (tmp_path / "run" / "result.json").unlink()
    rebuilt = _built_by(recording_recover, monkeypatch)
    recover(tmp_path / "run")
    crashed = _written(tmp_path / "run")
    assert rebuilt == [crashed] and crashed["reason"] == "crashed" and not crashed["completed"]
    assert crashed["signal"] is None and crashed["authenticated"] is None and "error" not in crashed
    same = set(ran) - {"reason", "completed", "wall_seconds", "pids", "recording", "signal", "authenticated"}
    assert {k: crashed[k] for k in same} == {k: ran[k] for k in same}  # the rest as the recording holds it
    assert crashed["recording"]["messages"] == ran["recording"]["messages"]


@pytest.mark.parametrize(("change", "where"), [
    ({"reason": "finished"}, "reason"),
    ({"engine": "zenoh"}, "engine"),
    ({"extra": 1}, "(top)"),
    ({"ticks": -1}, "ticks"),
    ({"radio": {"sent": 1}}, "radio"),
    ({"decision_ms": {"mean": 0.0, "p95": 0.0, "p99": 0.0}}, "decision_ms"),
    ({"error": "a failure without reason error"}, "(top)"),
    ({"base": {"cell": None, "known_cells": None, "known_fraction": None, "merged": None, "ticks": None}}, "(top)"),
    ({"schema_version": SCHEMA_VERSION + 1}, "schema_version"),
    ({"failed": ["robot0"]}, "failed/0"),
])
def test_the_schema_refuses_what_breaks_the_contract(memory_run: dict[str, Any], change: dict[str, Any],
                                                     where: str) -> None:
    with pytest.raises(ValueError, match=re.escape(f"\n  {where}: ")):
        validate_result(memory_run | change)


def test_a_report_from_a_robot_the_run_does_not_have_is_dropped() -> None:
    """A bus without authentication lets anyone put on ``ctl/report/r-1``: the fold keeps only the run's robots
    (else ``agent_peak_rss_kb`` and ``malformed_dropped_by`` gained robots that never ran)."""
    keys, mon = Keys("x"), Monitor(("r0", "r1"))
    rep = RobotReport(src="r-1", tick=1, seq=1, decisions=1, decision_ms_mean=1.0, decision_ms_p95=1.0, dropped=0,
                      peak_rss_kb=1)
    assert mon.feed(keys.report("r-1"), rep.encode()) is None and mon.malformed == 1 and mon.reports == {}
    assert mon.feed(keys.report("r1"), msgspec.structs.replace(rep, src="r1").encode()) is not None
    assert set(mon.reports) == {"r1"} and mon.dropped_by()["launcher"] == 1


def test_every_key_is_documented_and_the_schema_pins_the_version() -> None:
    from fleet_emu.launch import result as former  # the module's names before it moved, kept for one release

    assert (former.validate_result, former.result_schema, former.Result) == (validate_result, result_schema, fe.Result)
    schema = result_schema()
    assert schema["properties"]["schema_version"] == {"const": SCHEMA_VERSION}
    doc = (Path(__file__).resolve().parents[2] / "docs" / "reference" / "result.md").read_text()
    objects = [schema, *(schema["properties"][k] for k in ("radio", "pids", "realtime", "base", "relay")),
               schema["$defs"]["scenario"], schema["$defs"]["realtime_robot"], schema["$defs"]["relay_kind"]]
    keys = {k for obj in objects for k in obj["properties"]}
    missing = sorted(k for k in keys if f"`{k}`" not in doc)
    assert not missing, f"docs/reference/result.md leaves out {missing}"


def test_the_metrics_schema_marks_the_former_groups_deprecated_and_refuses_a_broken_group() -> None:
    """``metrics.json``'s schema is ``result.json``'s with the report's keys laid over: the groups the first layout
    named differently are the ones it marks deprecated, each saying its keys' one names; a group missing what
    ``result.json`` requires is refused."""
    schema = metrics_schema()
    deprecated = {k for k, v in schema["properties"].items() if v.get("deprecated")}
    assert deprecated == set(DEPRECATED_GROUPS) | {old for old in RENAMED if "." not in old}  # and renamed keys
    for group, names in DEPRECATED_GROUPS.items():
        said = schema["properties"][group]["description"]
        assert all(new.split(".")[0] in said for new in names.values()), group
    assert set(schema["properties"]["radio"]["required"]) >= {"dropped_loss", "per_robot", "by_kind"}
    assert "wall_seconds" not in schema["required"] and "t100" in schema["required"]
    with pytest.raises(ValueError, match=re.escape("\n  radio: 'delivered' is a required property")):
        validate_metrics({"radio": {"sent": 1}})


def test_a_renamed_key_is_written_under_its_old_name_too_and_the_schema_marks_it(memory_run: dict[str, Any]) -> None:
    """``robot_peak_rss_kb`` and ``pids.robots`` were ``agent_peak_rss_kb`` and ``pids.agents``: a reader of the
    old names keeps working for one release, and the schema says which are deprecated."""
    assert memory_run["agent_peak_rss_kb"] == memory_run["robot_peak_rss_kb"] and memory_run["robot_peak_rss_kb"]
    assert memory_run["pids"]["agents"] == memory_run["pids"]["robots"] and memory_run["pids"]["robots"]
    props = result_schema()["properties"]
    for old in RENAMED:
        outer, _, inner = old.partition(".")
        assert (props[outer]["properties"][inner] if inner else props[outer]).get("deprecated") is True, old
