"""An error names the setting as the user wrote it: the Python keyword from Python, the flag from ``fleet``."""

from __future__ import annotations

from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.spelling import cli_spelling, option
from fleet_emu.launch.outdir import refuse_held
from tests.conftest import run_cli


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
