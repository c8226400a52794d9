"""``fleet run``'s radio flags: one per :class:`RadioConfig` field, made from its declaration
(:func:`fleet_emu.core.radio.radio_settings`: flag, metavar, unit, range, help), so that a field declared there
is a flag here with nothing else to write."""

from __future__ import annotations

import argparse
from typing import Any

from fleet_emu.core.radio import radio_settings
from fleet_emu.launch.setting_flags import add_setting_flags, given


def add_radio_flags(parser: argparse.ArgumentParser) -> None:
    """A ``radio`` group of flags, ``--waf DB`` and the like, each defaulting to None (not given: the
    scenario's value)."""
    group = parser.add_argument_group("radio", "the scenario's [radio], one flag per setting "
                                               "(docs/guides/radio.md)")
    add_setting_flags(group, radio_settings())
    group.add_argument("--radio-profile", metavar="PROFILE.toml", default=None,
                       help="a measured radio profile (`fleet radio fit SITE --out PROFILE.toml`): its path loss, "
                            "dB per wall and range as the wall model's settings, under the radio flags given "
                            "(docs/guides/radio-measured.md)")


def radio_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The radio flags given, by field name, for :meth:`Scenario.override`; ``--radio-profile`` as a ``radio``
    table naming the profile (the flags given win over it)."""
    flags = given(args, radio_settings())
    profile = getattr(args, "radio_profile", None)
    return flags if profile is None else {"radio": {"profile": profile}, **flags}
