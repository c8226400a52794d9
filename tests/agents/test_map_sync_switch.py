"""The scenario's ``map_sync`` switch: on by default, off from a scenario file, a flag, ``override`` or a study;
off, a lossy run's robots never ask for nor resend a lost map delta, in the memory engine and in a robot's own
process alike (both build the brain from the scenario with ``brain_config``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet_emu.agents.brain import brain_config
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import validate_result


def test_on_by_default_absent_from_scenario_json_and_off_round_trips(tmp_path: Path) -> None:
    assert Scenario().map_sync is True and "map_sync" not in Scenario().to_dict()
    off = Scenario().override(map_sync=False, loss=0.3)
    assert off.to_dict()["map_sync"] is False
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(off.to_dict()))
    assert Scenario.load(path) == off
    toml = tmp_path / "s.toml"
    toml.write_text("map_sync = false\n[radio]\nloss = 0.3\n")
    assert Scenario.load(toml).map_sync is False


@pytest.mark.parametrize("value", ["no", 0, 1, [False]])
def test_a_bad_value_is_one_line(value: object) -> None:
    for make in (lambda: Scenario.from_dict({"map_sync": value}), lambda: Scenario().override(map_sync=value)):
        with pytest.raises(ConfigError, match="map_sync must be true or false") as exc:
            make()
        assert "\n" not in str(exc.value)


@pytest.mark.parametrize(("loss", "sync", "on"), [(0.3, True, True), (0.3, False, False), (0.0, True, True)])
def test_the_brain_syncs_only_when_asked_and_the_radio_can_lose(loss: float, sync: bool, on: bool) -> None:
    assert brain_config(Scenario().override(comm="wall", loss=loss, map_sync=sync)).map_sync is on


def test_the_flags_reach_the_scenario() -> None:
    from fleet_emu.launch.cli import build_parser, scenario_from_args

    for argv, want in ((["run"], True), (["run", "--no-map-sync"], False), (["run", "--map-sync"], True)):
        assert scenario_from_args(build_parser().parse_args(argv)).map_sync is want
    off = scenario_from_args(build_parser().parse_args(["run", "--no-map-sync"]))
    assert scenario_from_args(build_parser().parse_args(["run", "--scenario", "default", "--map-sync"])).map_sync
    assert off.override(map_sync=None).map_sync is False  # a flag not given keeps the scenario's


def _sync_counts(fleet: Fleet) -> tuple[int, int, int]:
    syncs = [b.sync for b in fleet.brains.values() if b.sync is not None]
    return len(syncs), sum(s.asked for s in syncs), sum(s.resent for s in syncs)


def test_off_in_the_memory_engine_a_lost_delta_is_not_asked_for_again() -> None:
    """Off at loss 0.3: no brain keeps sync state, so none asks for or resends a delta; the run is another run,
    which sends fewer bytes (no requests, no resent cells), and its result says so."""
    runs = {}
    for sync in (True, False):
        s = Scenario().override(map="office", robots=3, allocator="minpos", comm="full", loss=0.3, seed=2,
                                max_ticks=120, belief_every=0, map_sync=sync)
        fleet = Fleet(s)
        result = fleet.run()
        runs[sync] = (_sync_counts(fleet), result)
    (brains, asked, resent), on = runs[True]
    assert brains == 3 and asked > 0 and resent > 0
    counts, off = runs[False]
    assert counts == (0, 0, 0)
    assert off["radio"]["bytes_sent"] < on["radio"]["bytes_sent"]
    assert off["scenario"]["map_sync"] is False and "map_sync" not in on["scenario"]
    validate_result(off.data)


def test_off_reaches_a_robots_own_process(tmp_path: Path) -> None:
    """A robot's process reads the run's ``scenario.json`` (``core.node.parse_child``) and builds its node from
    it: the brain it builds has no map sync."""
    from fleet_emu.agents.node import RobotNode

    path = tmp_path / "scenario.json"
    for sync in (True, False):
        path.write_text(json.dumps(Scenario().override(loss=0.3, map_sync=sync).to_dict()))
        node = RobotNode(Scenario.from_json(path), "run", "r0")
        assert (node.brain.sync is not None) is sync
