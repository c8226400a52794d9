"""An error names the setting as the user wrote it: the Python keyword from Python, the flag from ``fleet``."""

from __future__ import annotations

from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.setting_names import cli_spelling, option
from fleet_emu.launch.outdir import refuse_held
from tests.harness.cli import run_cli


@pytest.mark.parametrize("flags, keyword, flag", [
    ({"loss": 1.5}, "loss", "--loss"), ({"max_ticks": 0}, "max_ticks", "--max-ticks"),
    ({"sensor_range": 0.1}, "sensor_range", "--sensor-range"), ({"relay_ttl": 99}, "relay_ttl", "--relay-ttl"),
])
def test_scenario_errors_name_the_keyword_from_python_and_the_flag_from_the_cli(
        flags: dict[str, object], keyword: str, flag: str) -> None:
    with pytest.raises(ConfigError) as exc:
        fe.Scenario().override(**flags)
    assert str(exc.value).startswith(f"{keyword} ") and "--" not in str(exc.value)
    with cli_spelling(), pytest.raises(ConfigError) as exc:
        fe.Scenario().override(**flags)
    assert str(exc.value).startswith(f"{flag} ")


def test_a_held_folder_says_overwrite_true_from_python(tmp_path: Path) -> None:
    (tmp_path / "result.json").write_text("{}")
    with pytest.raises(ConfigError, match=r"^out .* pass overwrite=True to replace it"):
        refuse_held(tmp_path, overwrite=False)
    with cli_spelling(), pytest.raises(ConfigError, match=r"^--out .* pass --overwrite to replace it"):
        refuse_held(tmp_path, overwrite=False)
    assert option("overwrite", "True") == "overwrite=True"


def test_the_cli_names_the_flag() -> None:
    code, _, err = run_cli(["run", "--loss", "1.5"])
    assert code == 2 and err == "fleet: error: --loss must be within [0, 1] (got 1.5)\n"


def test_run_options_name_their_keywords_from_python() -> None:
    with pytest.raises(ConfigError, match=r"^run_id must be letters"):
        fe.run(fe.Scenario(), run_id="a/b", engine="memory")  # was a ValueError's traceback on this engine
    with pytest.raises(ConfigError, match=r"^realtime_hz must be a number of ticks per second"):
        fe.run(fe.Scenario(), realtime_hz=-1)
    code, _, err = run_cli(["run", "--run-id", "a/b"])
    assert code == 2 and err.startswith("fleet: error: --run-id must be letters")


@pytest.mark.parametrize("toml, key", [
    ('[fleet]\nrobots = "three"\n', "[fleet] robots must be a whole number"),
    ("[radio]\nloss = 2\n", "[radio] loss must be within [0, 1]"),
    ("max_ticks = -1\n", "max_ticks must be from 1"),
    ('[map]\ncell_size = "big"\n', "[map] cell_size must be a finite number"),
    ('[allocator]\ntype = "mhm"\n', "[allocator] type mhm plans at the base station: it needs [fleet] base = true"),
])
def test_a_scenario_file_error_names_the_file_and_the_key_from_python_and_the_cli(
        toml: str, key: str, tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(toml)
    with pytest.raises(ConfigError) as exc:
        fe.Scenario.load(path)
    assert str(exc.value).startswith(f"scenario {path}: {key}"), exc.value
    code, _, err = run_cli(["run", str(path), "--engine", "memory", "--no-record"])
    assert code == 2 and err.startswith(f"fleet: error: scenario {path}: {key}") and "--" not in err, err


def test_a_flag_on_top_of_a_file_is_named_as_the_flag(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text("[fleet]\nrobots = 3\n")
    code, _, err = run_cli(["run", str(path), "--robots", "0", "--engine", "memory", "--no-record"])
    assert code == 2 and err == "fleet: error: --robots must be from 1 to 256 (got 0)\n", err


@pytest.mark.parametrize("grid, fleet, key", [
    ('robots = [2, "x"]', "", "[grid] robots must be a whole number"),
    ("robots = [2]", "loss = 3", "[fleet] loss must be within [0, 1]"),
    ("radio = [{waf = -3}]", "", "[grid] radio.waf must be within"),
    ("robots = [2]", "radio = {loss = 3}", "[fleet] radio.loss must be within"),
])
def test_a_study_file_error_names_the_file_and_the_key(grid: str, fleet: str, key: str, tmp_path: Path) -> None:
    from fleet_emu.sweep.study import Study

    path = tmp_path / "st.toml"
    path.write_text(f'[study]\nseeds = 1\n[grid]\nallocator = ["nearest"]\n{grid}\n[fleet]\n{fleet}\n')
    with pytest.raises(ConfigError) as exc:
        Study.load(path)
    assert str(exc.value).startswith(f"study {path}: {key}"), exc.value


@pytest.mark.parametrize("argv, hint", [
    (["run", "--allocator", "minpoz", "--engine", "memory"], "unknown allocator 'minpoz'; did you mean 'minpos'?"),
    (["run", "--map", "ofice", "--engine", "memory"], "unknown map 'ofice'; did you mean 'office'?"),
    (["sweep", "yan-los", "--out", "x"], "study yan-los not found; did you mean 'yan-loss'?"),
    (["run", "--robts", "3"], "unrecognized arguments: --robts; did you mean '--robots'?"),
    (["sweep", "docs-typo.toml", "--out", "x"], "map ofice not found; did you mean 'office'?"),
    (["rnu"], "did you mean 'run'?"),
])
def test_a_name_close_to_a_known_one_gets_did_you_mean(argv: list[str], hint: str, tmp_path: Path) -> None:
    (tmp_path / "docs-typo.toml").write_text('[study]\nseeds = 1\n[grid]\nallocator = ["nearest"]\nmap = ["ofice"]\n')
    code, _, err = run_cli(argv, cwd=tmp_path)
    assert code == 2 and hint in err and err.count("\n") == 1, err


def test_a_name_far_from_every_known_one_gets_only_the_list() -> None:
    code, _, err = run_cli(["run", "--allocator", "telepathy", "--engine", "memory"])
    assert code == 2 and "did you mean" not in err and "(known: " in err, err


def test_plural_forms() -> None:
    from fleet_emu.core.setting_names import plural

    assert [plural(n, "job") for n in (0, 1, 2)] == ["0 jobs", "1 job", "2 jobs"]
    assert plural(1, "policy", "policies") == "1 policy" and plural(3, "policy", "policies") == "3 policies"
