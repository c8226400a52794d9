"""The in-memory fleet's API (PettingZoo ``ParallelEnv``-like): reset(seed), step(), seeds, actions."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core import grid as fe_grid
from fleet_emu.core.scenario import BASE_PLANNERS
from fleet_emu.launch.memory import Fleet, seed_test
from fleet_emu.launch.result import deterministic
from fleet_emu.world.sim import StartAreaError
from tests.harness.files import draw_map

ROOMS = """
##################
#.......#........#
#.......#........#
#................#
#.......#........#
####.#######.#####
#.......#........#
#................#
#.......#........#
##################
"""


@pytest.fixture(scope="module")
def rooms(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return draw_map(ROOMS, tmp_path_factory.mktemp("maps") / "rooms.png")


def scenario(rooms: Path, **over: object) -> fe.Scenario:
    base = {"map": str(rooms), "cell_size": 0.5, "robots": 3, "loss": 0.3, "sensor_range": 1.5, "max_ticks": 200,
            "start": (1, 1)}
    return fe.Scenario().override(**(base | over))


@pytest.mark.parametrize("allocator", allocator_names())
def test_seed_test_passes_for_every_allocator(allocator: str, rooms: Path) -> None:
    base = {"base": True} if allocator in BASE_PLANNERS else {}  # mhm plans at a base station
    seed_test(scenario(rooms, allocator=allocator, **base), seed=3, ticks=40)


def test_reset_and_step_follow_parallel_env(rooms: Path) -> None:
    env = Fleet(scenario(rooms, allocator="nearest"))
    obs, infos = env.reset(seed=7)
    assert env.scenario.seed == 7 and env.agents == env.possible_agents == ["r0", "r1", "r2"]
    assert set(obs) == set(infos) == set(env.agents) and all(o.tick == 0 for o in obs.values())
    total = env.world.coverage
    while not env.done:
        obs, rewards, terms, truncs, infos = env.step()
        total += next(iter(rewards.values()), 0.0)
    assert env.reason == "coverage" and all(terms.values()) and not any(truncs.values())
    assert obs == {} and env.agents == []
    assert total == pytest.approx(env.world.coverage)
    res = env.result()
    assert res.completed and res["engine"] == "memory" and res["seed"] == 7 and res.ticks == env.world.tick
    with pytest.raises(fe.RunError, match="reset"):
        env.step()


def test_actions_replace_the_brains_moves(rooms: Path) -> None:
    env = Fleet(scenario(rooms, allocator="nearest", robots=1))
    env.reset(seed=0)
    start = env.world.poses["r0"]
    assert start == (1, 1)
    env.step({"r0": (1, 0)})  # down, whatever the brain wanted
    env.step({"r0": (0, 0)})
    assert env.world.poses["r0"] == (2, 1) and env.result()["path_length"] == [1]


def test_seeds_change_the_run_and_a_tick_limit_truncates(rooms: Path) -> None:
    a = Fleet(scenario(rooms, start="random", max_ticks=12)).run(seed=1)
    b = Fleet(scenario(rooms, start="random", max_ticks=12)).run(seed=2)
    assert a.curve != b.curve
    env = Fleet(scenario(rooms, max_ticks=3))
    env.reset()
    for _ in range(3):
        _, _, terms, truncs, _ = env.step()
    assert env.done and env.reason == "max_ticks" and all(truncs.values()) and not any(terms.values())


def test_bad_scenario_is_refused_before_any_reset(rooms: Path) -> None:
    with pytest.raises(fe.ConfigError, match="no_such"):
        Fleet(scenario(rooms).override(allocator="no_such"))


@pytest.mark.parametrize(("comm", "loss", "applied"), [("ideal", 0.3, 0.0), ("full", 0.3, 0.3), ("disk", 0.2, 0.2)])
def test_result_and_recording_state_the_radio_model_and_the_loss_applied(
        comm: str, loss: float, applied: float, rooms: Path, tmp_path: Path) -> None:
    from mcap.reader import make_reader

    from fleet_emu.launch.memory import run_memory

    res = run_memory(scenario(rooms, comm=comm, loss=loss, max_ticks=30), tmp_path / "run", run_id="radio")
    assert (res["comm"], res["loss"], res["loss_applied"]) == (comm, loss, applied)
    assert (res["radio"]["dropped_loss"] > 0) == (applied > 0)
    with open(tmp_path / "run" / "run.mcap", "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}["scenario"]
    assert (meta["radio_model"], float(meta["loss_applied"])) == (comm, applied)
    assert fe.load_recording(tmp_path / "run").result["loss_applied"] == applied


def test_a_signal_ends_a_memory_run_after_the_tick_and_keeps_its_files(rooms: Path, tmp_path: Path) -> None:
    import signal

    from mcap.reader import make_reader

    from fleet_emu.launch.memory import run_memory
    from fleet_emu.launch.signals import Interrupts

    irq = Interrupts()

    def progress(m: object) -> None:
        if getattr(m, "tick", 0) == 5:
            irq._handle(signal.SIGTERM, None)

    s = fe.Scenario().override(map=str(rooms), cell_size=0.5, robots=2, max_ticks=10000, seed=2)
    res = run_memory(s, tmp_path / "run", on_progress=progress, interrupts=irq).data
    assert res["reason"] == "interrupted" and res["signal"] == "SIGTERM" and 5 <= res["ticks"] <= 6
    assert res["completed"] is False and (tmp_path / "run" / "result.json").exists()
    with open(tmp_path / "run" / "run.mcap", "rb") as f:
        assert make_reader(f).get_summary() is not None


def test_explicit_start_cells_and_a_drawn_map() -> None:
    """``Fleet(map_data=..., starts=...)``: robots on the cells given (a dict or one per robot in order), on a
    map drawn here; a fleet reset again with the same seed replays its run; bad cells are one-line errors."""
    grid, _ = fe_grid.from_ascii(ROOMS)
    drawn = fe_grid.MapData("drawn", grid, 0.5, (1, 1))
    s = fe.Scenario(map="drawn", robots=3, sensor_range=1.5, max_ticks=40, seed=2)
    starts = {"r0": (8, 16), "r1": (1, 1), "r2": (3, 9)}
    env = Fleet(s, map_data=drawn, starts=starts)
    obs, _ = env.reset()
    assert {r: o.cell for r, o in obs.items()} == starts and env.world.start == (8, 16)
    first = env.run().data
    again = Fleet(s, map_data=drawn, starts=list(starts.values())).run().data
    assert deterministic(first) == deterministic(again)
    with pytest.raises(StartAreaError, match="starts must give a cell for each of the robots r0, r1, r2"):
        Fleet(s, map_data=drawn, starts={"r0": (1, 1)})
    with pytest.raises(StartAreaError, match=r"start cell \(0, 0\) is not a free cell"):
        Fleet(s, map_data=drawn, starts=[(1, 1), (0, 0), (3, 9)]).reset()


def test_a_base_station_in_memory_and_the_summary_row() -> None:
    """The memory engine with a base (``base = true``: at the start cell), its result keys, and the closing
    table's row; the same run without a base has neither and the robots do the same."""
    from rich.console import Console

    from fleet_emu.recording.tables import summary_table

    s = fe.Scenario().override(map="office", robots=2, comm="disk", comm_range=3.0, seed=2, max_ticks=40, base=True)
    res = Fleet(s).run().data
    frac = res["base_connected_fraction"]
    assert set(frac["per_robot"]) == {"r0", "r1"} and 0 <= frac["all_ticks"] <= frac["overall"] <= 1
    assert res["base"]["ticks"] == res["ticks"] == 40 and res["base"]["known_cells"] > 0
    assert res["pids"]["base"] == res["pids"]["world"]
    console = Console(width=200, record=True, file=io.StringIO())
    console.print(summary_table(res, "x"))
    text = console.export_text()
    assert "base connected" in text and f"base at {res['base']['cell']}" in text
    plain = Fleet(s.override(base=False)).run().data
    assert "base" not in plain and "base_connected_fraction" not in plain and "base" not in plain["pids"]
    assert (plain["path_length"], plain["coverage"]) == (res["path_length"], res["coverage"])


def test_the_summary_never_shows_none_and_names_the_hosts() -> None:
    """A run that stopped short of 90 % has no t90: the summary shows ``-``, as the report does; a run with robots
    on hosts says which ran where."""
    from rich.console import Console

    from fleet_emu.recording.tables import summary_table

    res = Fleet(fe.Scenario().override(map="office", robots=2, seed=1, max_ticks=10)).run().data
    assert res["t90"] is None and res["t99"] is None
    for data in (res, {**res, "pids": {**res["pids"], "hosts": {"host0": ["r1"]}}}):
        console = Console(width=200, record=True, file=io.StringIO())
        console.print(summary_table(data, "x"))
        text = console.export_text()
        row = next(line for line in text.splitlines() if "t90 / t99" in line)
        assert "None" not in text and row.strip("│ ").endswith("- / -"), text
    assert any("on hosts" in line and "host0: r1" in line for line in text.splitlines()), text
