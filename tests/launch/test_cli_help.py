"""``fleet``'s help: a bare ``fleet`` explains itself instead of starting a fleet, and every ``fleet run`` flag
says what it takes and what it defaults to."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from fleet_emu.cli import build_parser
from fleet_emu.launch.cli import START_HINT, scenario_from_args
from tests.harness.cli import run_cli


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


def test_the_default_scenario_is_the_declared_defaults() -> None:
    """The flags' help shows each setting's declared default as the default: the shipped default scenario, which
    a bare ``fleet run`` runs, is those defaults."""
    from fleet_emu.core.radio import RadioConfig
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.cli import DEFAULT_SCENARIO

    assert Scenario.load(DEFAULT_SCENARIO) == Scenario(radio=RadioConfig())


def _parser(command: str) -> argparse.ArgumentParser:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_every_flag_shows_its_declared_range_and_default(command: str) -> None:
    """Each flag made from a declared setting (a scenario's or its radio's for ``run``, ``sweep``'s own numbers)
    shows that declaration's range and default; every other flag with a default or a number says its default."""
    from fleet_emu.core.radio import radio_settings
    from fleet_emu.core.scenario import scenario_settings
    from fleet_emu.sweep.options import sweep_settings

    specs = (*scenario_settings(), *radio_settings()) if command == "run" else sweep_settings()
    declared = {s.name: s for s in specs if s.cli and not s.table}
    seen = set()
    for action in _parser(command)._actions:
        if not action.option_strings or action.dest == "help":
            continue
        text = " ".join((action.help or "").split())
        spec = declared.get(action.dest)
        if spec is not None:
            seen.add(spec.name)
            assert spec.flag in action.option_strings
            if spec.kind is not bool:
                assert spec.span() in text, f"{spec.flag}: no range {spec.span()!r}: {text}"
            assert f"(default: {spec.shown()}" in text, f"{spec.flag}: no default {spec.shown()!r}: {text}"
        elif action.type in (int, float) or action.default not in (None, False):
            assert "default" in text, f"{action.option_strings[0]} does not say its default: {text}"
    assert seen == set(declared)  # every declared setting is a flag


def test_sweep_numbers_are_checked_by_their_declaration(tmp_path: Path) -> None:
    """``fleet sweep``'s numbers are declared once (sweep/options.py): out of range is one line naming the flag,
    and the confidence level's default is the intervals' own."""
    from fleet_emu.sweep.intervals import Bootstrap
    from fleet_emu.sweep.options import SweepOptions

    assert SweepOptions().level == Bootstrap().level
    for argv, line in ((["--jobs", "0"], "--jobs must be from 1 to 4096 (got 0)"),
                       (["--until-decided", "--level", "2"], "--level must be within [0.5, 0.999] (got 2.0)"),
                       (["--until-decided", "--max-seeds", "0"], "--max-seeds must be from 1 to 1000000 (got 0)")):
        code, _, err = run_cli(["sweep", "benavides", "--out", str(tmp_path / "out"), *argv])
        assert (code, err) == (2, f"fleet: error: {line}\n")
    assert not (tmp_path / "out").exists()
