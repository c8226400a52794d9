"""``fleet``'s help: a bare ``fleet`` explains itself instead of starting a fleet, and every ``fleet run`` flag
says what it takes and what it defaults to."""

from __future__ import annotations

import argparse
from pathlib import Path

from fleet_emu.cli import build_parser
from fleet_emu.launch.cli import START_HINT, scenario_from_args
from tests.conftest import run_cli


def _run_parser() -> argparse.ArgumentParser:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices["run"]


def test_bare_fleet_prints_help_and_starts_nothing(tmp_path: Path) -> None:
    code, out, _ = run_cli([], cwd=tmp_path)
    assert code == 0
    assert "usage: fleet" in out and START_HINT in out and "`fleet run`" in START_HINT
    assert list(tmp_path.iterdir()) == []  # no runs/ folder: nothing ran


def test_every_run_flag_has_help_and_every_number_a_default_and_a_range() -> None:
    for action in _run_parser()._actions:
        if not action.option_strings or action.dest == "help":
            continue
        assert action.help, f"{action.option_strings[0]} has no help"
        if action.type in (int, float):
            text = " ".join(action.help.split())
            assert "default" in text, f"{action.option_strings[0]} does not say its default: {text}"
            assert any(w in text for w in ("from ", "within ", ">")), f"{action.option_strings[0]}: no range: {text}"


def test_quiet_says_it_drops_the_summary() -> None:
    quiet = next(a for a in _run_parser()._actions if "--quiet" in a.option_strings)
    assert quiet.help is not None and "summary" in quiet.help


def test_tick_s_flag_sets_the_scenario() -> None:
    args = build_parser().parse_args(["run", "--tick-s", "0.25"])
    assert scenario_from_args(args).tick_s == 0.25
    assert scenario_from_args(build_parser().parse_args(["run"])).tick_s == 1.0


def test_the_help_s_defaults_are_the_default_scenario_s() -> None:
    """The flags' help reads the default scenario's TOML without building it (no allocator loaded for a help
    text); the values it shows are the built scenario's."""
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.cli import DEFAULT_SCENARIO, default_values

    built, read = Scenario.load(DEFAULT_SCENARIO), default_values()
    for field in ("map", "robots", "sensor_range", "seed", "max_ticks", "target_coverage"):
        assert read[field] == getattr(built, field), field
    assert read["allocator"] == built.allocator["type"]
