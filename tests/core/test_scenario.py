from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.core.keys import Keys, key, robot_ids
from fleet_emu.core.rng import derive_seed, generator
from fleet_emu.core.scenario import ConfigError, Scenario, load_scenario, with_overrides

DEFAULT = Path(__file__).resolve().parents[2] / "launch" / "scenarios" / "default.toml"


def test_default_scenario_matches_design() -> None:
    s = load_scenario(DEFAULT).validate()
    assert (s.map, s.robots, s.allocator["type"], s.radio.loss, s.radio.comm) == ("office", 4, "minpos", 0.1, "wall")
    assert Scenario.from_dict(s.to_dict()) == s


@pytest.mark.parametrize("flags, match", [
    ({"robots": 0}, "robots"), ({"loss": 1.5}, "loss"), ({"loss": -0.1}, "loss"),
    ({"sensor_range": -1.0}, "sensor-range"), ({"comm_range": 0.0}, "comm-range"),
    ({"target_coverage": 0.0}, "target-coverage"), ({"max_ticks": 0}, "max-ticks"),
])
def test_bad_values_fail_with_one_line(flags: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as exc:
        with_overrides(Scenario(), **flags).validate()
    assert "\n" not in str(exc.value)


def test_overrides_and_toml_errors(tmp_path: Path) -> None:
    s = with_overrides(Scenario(), robots=3, loss=0.3, allocator="nearest", seed=None)
    assert (s.robots, s.radio.loss, s.allocator, s.seed) == (3, 0.3, {"type": "nearest"}, 0)
    bad = tmp_path / "bad.toml"
    bad.write_text("robots = [")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_scenario(bad)
    with pytest.raises(ConfigError, match="not found"):
        load_scenario(tmp_path / "missing.toml")
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("[fleet]\nrobotz = 3\n")
    with pytest.raises(ConfigError, match="robotz"):
        load_scenario(unknown)


def test_keys_and_seeds() -> None:
    k = Keys("run1")
    assert k.obs("r2") == "fleet/run1/world/obs/r2"
    assert k.cmd("r0") == "fleet/run1/robot/r0/cmd"
    assert k.tx("r1") == "fleet/run1/radio/tx/r1" and k.rx("r1") == "fleet/run1/radio/rx/r1"
    assert k.links == "fleet/run1/netem/links" and k.alive("agent", "r3") == "fleet/run1/alive/agent/r3"
    assert Keys.last(k.tx("r11")) == "r11"
    with pytest.raises(ValueError):
        key("a/b")
    assert robot_ids(3) == ["r0", "r1", "r2"]
    assert derive_seed(1, "r0") == derive_seed(1, "r0") != derive_seed(1, "r1")
    assert generator(5, "netem").random() == generator(5, "netem").random()
