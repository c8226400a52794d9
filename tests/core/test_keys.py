"""Key expressions: built by one function, parsed back by one method."""

from __future__ import annotations

import pytest

from fleet_emu.core.keys import Keys, ParsedKey, key, robot_ids


def test_every_key_parses_back_to_what_built_it() -> None:
    k = Keys("run1")
    assert k.obs("r2") == "fleet/run1/world/obs/r2"
    assert k.cmd("r0") == "fleet/run1/robot/r0/cmd"
    assert k.tx("r1") == "fleet/run1/radio/tx/r1" and k.rx("r1") == "fleet/run1/radio/rx/r1"
    assert k.links == "fleet/run1/netem/links" and k.alive("agent", "r3") == "fleet/run1/alive/agent/r3"
    built = {
        k.obs("r2"): ParsedKey("obs", "r2"), k.state: ParsedKey("state"), k.cmd("r11"): ParsedKey("cmd", "r11"),
        k.belief("r0"): ParsedKey("belief", "r0"), k.tx("r1"): ParsedKey("tx", "r1"),
        k.rx("r3"): ParsedKey("rx", "r3"), k.links: ParsedKey("links"), k.hello: ParsedKey("hello"),
        k.ready("netem"): ParsedKey("ready", "netem"), k.stop: ParsedKey("stop"),
        k.failed("r1"): ParsedKey("failed", "r1"), k.report("r2"): ParsedKey("report", "r2"),
        k.alive("agent", "r4"): ParsedKey("alive", "r4", "agent"),
        k.clock: ParsedKey("clock"), k.timing("r5"): ParsedKey("timing", "r5"),  # real-time runs only
    }
    for expr, parsed in built.items():
        assert k.parse(expr) == parsed, expr
        assert k.channel(expr) == parsed.channel, expr


@pytest.mark.parametrize("expr", [
    "fleet/run2/world/state",  # another run
    "fleet/run1/world/obs",  # a robot id missing
    "fleet/run1/robot/r1/cmd/extra",  # one chunk too many
    "fleet/run1/radio/sideways/r1",
    "other/run1/world/state",
    "fleet/run1",
    "",
])
def test_foreign_or_malformed_keys_parse_to_none(expr: str) -> None:
    assert Keys("run1").parse(expr) is None and Keys("run1").channel(expr) is None


def test_run_ids_and_robot_ids() -> None:
    with pytest.raises(ValueError):
        key("a/b")
    assert robot_ids(3) == ["r0", "r1", "r2"]


@pytest.mark.parametrize("radio", [False, True])
def test_the_launcher_without_a_recording_subscribes_to_what_its_fold_reads(radio: bool) -> None:
    """``Keys.folded``: the channels the monitor folds (recording/monitor.py), the world's hello the launcher
    answers, and the radio bundles only in a relaying run; never the observations, rx bundles and beliefs."""
    from fleet_emu.recording.monitor import _FOLDED, _RADIO

    keys = Keys("run1")
    channels = {keys.parse(k.replace("*", "r3")).channel for k in keys.folded(radio)}  # type: ignore[union-attr]
    assert channels == _FOLDED | {"hello"} | (_RADIO if radio else set())
    assert not {"obs", "belief", "ready", "failed"} & channels
