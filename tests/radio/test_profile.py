"""A radio profile (core/radio_profile.py): checked like [radio], and a scenario that names it gets eq. 4 with
the fitted values, so that the emulator's link decision is the fitted RSS against the sensitivity."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import pytest

import fleet_emu as fe
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.radio import signal_db
from fleet_emu.core.radio_profile import ProfileValues, RadioProfile, load_profile, parse_profile, profile_text

GOOD: dict[str, Any] = {"model": "wall", "p0_dbm": -48.0, "path_loss": 1.5, "waf": 8.0, "max_walls": 2,
                        "sensitivity_dbm": -93.0}


def test_a_profile_becomes_eq_4_whose_signal_is_the_margin_above_the_sensitivity() -> None:
    profile = parse_profile(dict(GOOD), "p")
    radio = fe.Scenario().override(radio=profile.radio_table()).radio
    v = profile.values
    for d, walls in ((0.5, 0), (3.0, 1), (12.0, 3), (40.0, 0)):
        rss = v.p0_dbm - 10 * v.path_loss * math.log10(d) - v.waf * min(walls, v.max_walls)
        assert signal_db(d, walls, radio) == pytest.approx(rss - v.sensitivity_dbm)
    assert radio.threshold == 0 and radio.sure_range == pytest.approx(
        10 ** ((v.p0_dbm - v.sensitivity_dbm - v.max_walls * v.waf) / (10 * v.path_loss)))


def test_a_profile_round_trips_through_its_file() -> None:
    p = RadioProfile(ProfileValues(**GOOD, tag_height=1.3), site="s", anchor_p0_dbm=(-47.0, -49.5))
    assert parse_profile(tomllib.loads(profile_text(p, ["a comment"])), "p") == p
    assert p.p0_of(2) == (-47.0, -49.5)
    with pytest.raises(ConfigError, match="a P0 for 2 anchors, the site has 3"):
        p.p0_of(3)


@pytest.mark.parametrize(("change", "message"), [
    ({"wafx": 1.0}, "unknown key\\(s\\) wafx"),
    ({"waf": -1.0}, "waf must be within \\[0, 1000\\] dB \\(got -1.0\\)"),
    ({"path_loss": 0.0}, "path_loss must be within \\(0, 100\\]"),
    ({"max_walls": 1.5}, "max_walls must be from 0 to"),
    ({"model": "disk"}, "model must be one of wall, log-distance"),
    ({"anchor_p0_dbm": [-40.0, "x"]}, "anchor_p0_dbm must be a list of numbers"),
    ({"p0_dbm": 100.0, "path_loss": 0.01}, "free-space range of"),
    ({"model": "log-distance"}, "a log-distance profile counts no walls"),
])
def test_a_bad_profile_is_one_line_naming_the_file(change: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message) as exc:
        parse_profile({**GOOD, **change}, "radio profile p.toml")
    assert str(exc.value).startswith("radio profile p.toml: ") and "\n" not in str(exc.value)
    with pytest.raises(ConfigError, match="missing key\\(s\\) sensitivity_dbm"):
        parse_profile({k: v for k, v in GOOD.items() if k != "sensitivity_dbm"}, "p")


def test_a_scenario_names_a_profile_beside_it_and_its_own_keys_win(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "p.toml").write_text(profile_text(parse_profile(dict(GOOD), "p"), []))
    (tmp_path / "s.toml").write_text('[radio]\nprofile = "sub/p.toml"\nwaf = 5.0\nloss = 0.2\n')
    radio = fe.Scenario.load(tmp_path / "s.toml").radio
    assert (radio.comm, radio.path_loss, radio.max_walls, radio.waf, radio.loss) == ("wall", 1.5, 2, 5.0, 0.2)
    assert radio.comm_range == pytest.approx(10 ** (45 / 15))
    same = fe.Scenario().override(radio={"profile": str(tmp_path / "sub" / "p.toml")}, waf=5.0)
    assert same.radio.comm_range == radio.comm_range and same.radio.waf == 5.0
    (tmp_path / "t.toml").write_text('[radio]\nprofile = "missing.toml"\n')
    with pytest.raises(ConfigError, match=r"missing\.toml: no such file"):
        fe.Scenario.load(tmp_path / "t.toml")
    assert load_profile(tmp_path / "sub" / "p.toml").values.waf == 8.0
