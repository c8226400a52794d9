"""A radio profile: a signal model fitted to measurements (``fleet radio fit``, docs/guides/radio-measured.md),
kept in a TOML file that a scenario names (``[radio] profile = "PROFILE.toml"``, ``fleet run --radio-profile``).

A profile holds the model in dBm, with a reference power ``p0_dbm`` at 1 m::

    RSS = p0_dbm - 10 * path_loss * log10(d / 1 m) - min(nW, max_walls) * waf

and the receiver's ``sensitivity_dbm``. It becomes eq. 4 of ``[radio]`` (``core/radio.py``) exactly: the same
``path_loss``, ``waf`` and ``max_walls``, ``threshold`` 0 dB, and ``comm_range`` the free-space distance at which
the signal falls to the sensitivity, ``10 ** ((p0_dbm - sensitivity_dbm) / (10 * path_loss))`` metres; eq. 4's
``P_ij`` is then the margin above the sensitivity in dB, and a link exists when the fitted RSS reaches it. A
per-anchor profile (``anchor_p0_dbm``, one P0 per anchor) gives a run the mean of its anchors' P0 (``p0_dbm``):
robots are alike.

Each value is declared once with :func:`~fleet_emu.core.fields.setting`, as ``[radio]``'s are, and checked the
same way; an unknown key or a value out of range is one line naming the file.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.fields import Setting, setting, settings
from fleet_emu.core.limits import check_size

PROFILE_MODELS = ("wall", "log-distance")
#: Keys a profile may hold besides its settings: the site it was fitted on, and one P0 per anchor.
EXTRA_KEYS = ("site", "anchor_p0_dbm")
#: Keys a profile must hold.
REQUIRED_KEYS = ("model", "p0_dbm", "path_loss", "sensitivity_dbm")


@dataclasses.dataclass(frozen=True)
class ProfileValues:
    """A profile's model and numbers, each declared with :func:`~fleet_emu.core.fields.setting`."""

    model: str = setting("wall", choices=PROFILE_MODELS, help="the model fitted: wall or log-distance")
    p0_dbm: float = setting(-40.0, unit="dBm", low=-200.0, high=100.0, help="received power at 1 m")
    path_loss: float = setting(2.0, low=0.0, high=100.0, low_open=True, help="path-loss exponent n")
    waf: float = setting(0.0, unit="dB", low=0.0, high=1000.0, help="attenuation per wall")
    max_walls: int = setting(0, low=0, high=10**6, help="most walls counted")
    sensitivity_dbm: float = setting(-93.0, unit="dBm", low=-200.0, high=100.0,
                                     help="the weakest signal a receiver hears")
    tag_height: float = setting(0.0, unit="m", low=0.0, high=1000.0,
                                help="the transmitter's height in the fit (fleet radio predict uses it)")
    resolution: float = setting(0.05, unit="m", low=0.001, high=1.0, help="the grid cell the walls were counted on")


@dataclasses.dataclass(frozen=True)
class RadioProfile:
    """A fitted signal model (the module docstring gives its equation and how a run uses it): its ``values``,
    the site it was fitted on and, per anchor, one P0 each (empty: one P0 for all)."""

    values: ProfileValues
    site: str = ""
    anchor_p0_dbm: tuple[float, ...] = ()

    @property
    def comm_range(self) -> float:
        """The free-space distance in metres at which the signal falls to the sensitivity."""
        v = self.values
        return float(10 ** ((v.p0_dbm - v.sensitivity_dbm) / (10 * v.path_loss)))

    def radio_table(self) -> dict[str, Any]:
        """The ``[radio]`` settings this profile stands for (the module docstring says how)."""
        v = self.values
        return {"comm": "wall", "path_loss": v.path_loss, "waf": v.waf, "max_walls": v.max_walls,
                "comm_range": self.comm_range, "threshold": 0.0}

    def p0_of(self, anchors: int) -> tuple[float, ...]:
        """The P0 of each of ``anchors`` anchors: the profile's per-anchor ones, or its one P0 for each."""
        if not self.anchor_p0_dbm:
            return (self.values.p0_dbm,) * anchors
        if len(self.anchor_p0_dbm) != anchors:
            raise ConfigError(f"the profile has a P0 for {len(self.anchor_p0_dbm)} anchors, the site has {anchors}")
        return self.anchor_p0_dbm


@functools.cache
def profile_settings() -> tuple[Setting, ...]:
    """The declaration of every :class:`ProfileValues` field, in order."""
    return settings(ProfileValues)


def parse_profile(raw: dict[str, Any], where: str) -> RadioProfile:
    """A profile from its TOML table; a one-line ConfigError (``where``: the file) on an unknown key, a missing
    one or a value out of range."""
    specs = {s.name: s for s in profile_settings()}
    known = [*specs, *EXTRA_KEYS]
    bad = sorted(set(raw) - set(known))
    if bad:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(bad)} (known: {', '.join(known)})")
    missing = [k for k in REQUIRED_KEYS if k not in raw]
    if missing:
        raise ConfigError(f"{where}: missing key(s) {', '.join(missing)}")
    for name, value in raw.items():
        if name in specs:
            try:
                specs[name].check(value)
            except ConfigError:
                raise ConfigError(f"{where}: {name} must be {specs[name].span()} (got {value!r})") from None
    site = raw.get("site", "")
    if not isinstance(site, str):
        raise ConfigError(f"{where}: site must be a string (got {site!r})")
    p0s = raw.get("anchor_p0_dbm", [])
    if not isinstance(p0s, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and -200 <= v <= 100
            for v in p0s):
        raise ConfigError(f"{where}: anchor_p0_dbm must be a list of numbers within [-200, 100] dBm (got {p0s!r})")
    values = ProfileValues(**{k: v for k, v in raw.items() if k in specs})
    if values.model == "log-distance" and (values.waf or values.max_walls):
        raise ConfigError(f"{where}: a log-distance profile counts no walls (waf and max_walls 0; got waf "
                          f"{values.waf:g}, max_walls {values.max_walls})")
    profile = RadioProfile(values, site=site, anchor_p0_dbm=tuple(float(v) for v in p0s))
    try:
        reach = profile.comm_range
    except OverflowError:
        reach = math.inf
    if not 0 < reach <= 1e6:
        raise ConfigError(f"{where}: p0_dbm {values.p0_dbm:g}, sensitivity_dbm {values.sensitivity_dbm:g} and "
                          f"path_loss {values.path_loss:g} give a free-space range of {reach:.3g} m, not within "
                          "(0, 1e6] m (the radio's comm_range)")
    return profile


def load_profile(path: str | Path) -> RadioProfile:
    """The profile in the TOML file ``path``; a one-line ConfigError when it cannot be read or is not one."""
    p = Path(path)
    where = f"radio profile {p}"
    try:
        if p.is_file():
            check_size(p.stat().st_size, where)
        raw = tomllib.loads(p.read_text())
    except FileNotFoundError:
        raise ConfigError(f"{where}: no such file (`fleet radio fit SITE --out {p}` writes one)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {where}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where} is not valid TOML: {exc}") from None
    return parse_profile(raw, where)


def profile_text(profile: RadioProfile, header: list[str]) -> str:
    """The TOML of ``profile``, ``header`` as comment lines above it (what the fit scored, how it was run)."""
    lines = [f"# {h}" for h in header]
    for s in profile_settings():
        v = getattr(profile.values, s.name)
        lines.append(f"{s.name} = " + (f'"{v}"' if isinstance(v, str) else repr(round(v, 4) if isinstance(v, float)
                                                                                else v)))
    if profile.site:
        lines.append(f'site = "{profile.site}"')
    if profile.anchor_p0_dbm:
        lines.append("anchor_p0_dbm = [" + ", ".join(f"{v:.4g}" for v in profile.anchor_p0_dbm) + "]")
    return "\n".join(lines) + "\n"


def radio_of_profile(table: dict[str, Any], base: Path | None = None) -> dict[str, Any]:
    """A ``[radio]`` table with ``profile = "PROFILE.toml"`` (a path relative to ``base``, the scenario's
    folder) replaced by the profile's settings; the table's other keys win over the profile's."""
    if "profile" not in table:
        return table
    rest = dict(table)
    name = rest.pop("profile")
    if not isinstance(name, str) or not name:
        raise ConfigError(f"[radio] profile must be a file name (got {name!r})")
    path = Path(name) if base is None or Path(name).is_absolute() else base / name
    return {**load_profile(path).radio_table(), **rest}
