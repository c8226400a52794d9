"""Fault trials, a few of each, with real processes (``benchmarks/fault_trials.py`` runs them by the hundred):
kill -9 of a random robot at a random tick, SIGINT at a random moment, fuzzed messages on every key, and
heavy loss. Each trial checks every invariant of a fault trial (``tests/harness/faults.py``: the run ended, result.json
is there, run.mcap reads to the end with result.json's count, no orphan, no death but the kill, the right exit
code); a failing trial lists what it broke."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.access import allowed_src
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.keys import Keys
from fleet_emu.core.scenario import BASE_PLANNERS
from tests.harness.cli import ENDLESS, result, run_cli
from tests.harness.faults import RunSpec, Trial, fuzz_trial, kill_trial, loss_trial, sigint_trial
from tests.harness.fuzz import UNKNOWN, fuzz_messages

SEED = 12


def _spec(small_map: Path, max_ticks: int = 50) -> RunSpec:
    """Three robots with a short sensor on the two-room map: about 70 ticks to see every cell."""
    return RunSpec(str(small_map), robots=3, max_ticks=max_ticks, target_coverage=1.0, seed=SEED,
                   extra=("--sensor-range", "1.0"))


def _ok(t: Trial) -> None:
    assert t.failures == [], f"{t.label}: {t.failures} {t.notes}"


def test_open_fuzz_is_never_a_message_a_node_may_accept() -> None:
    """What an outsider sends either does not decode, or names a sender that may not write on its key, or comes
    from a robot the fleet does not have on that robot's own key."""
    import fleet_emu.agents.allocators  # noqa: F401  (registers every payload kind)

    mutations: set[str] = set()
    for key, data, mutation in fuzz_messages(np.random.default_rng(SEED), "fz", ["r0", "r1", "r2"], 5000):
        mutations.add(mutation)
        try:
            msg = decode(data)
        except DecodeError:
            continue
        parsed = Keys("fz").parse(key)
        assert parsed is not None, key
        allowed = allowed_src(parsed)
        assert allowed is not None and (msg.src not in allowed or parsed.node in UNKNOWN), (key, mutation, msg)
    assert mutations >= {"bytes", "shape", "field", "kind", "version", "spoof", "unknown", "oversized"}


@pytest.mark.parametrize("i", [0, pytest.param(1, marks=pytest.mark.slow)])  # a second draw: -m slow
def test_kill9_of_a_random_robot_at_a_random_tick(small_map: Path, tmp_path: Path, i: int) -> None:
    """The robot is failed and the run goes on to its own end without it; exit 1 and one line naming it."""
    t = kill_trial(_spec(small_map), tmp_path, np.random.default_rng([SEED, 1, i]), f"kill{i}", window=30)
    assert t.notes == [], t.notes  # the robot was killed while the run went on
    _ok(t)
    assert t.exit_code == 1 and len(t.result["failed"]) == 1  # a robot of the fleet failed: never a silent 0
    assert t.result["reason"] in ("coverage", "max_ticks", "stall") and t.result["coverage"] > 0.5
    err = (tmp_path / f"kill{i}.stderr").read_text()
    assert err.strip().splitlines()[-1].startswith(f"fleet: error: robot(s) {t.result['failed'][0]} of 3 failed"), \
        err[-2000:]


@pytest.mark.parametrize("i", [0, pytest.param(1, marks=pytest.mark.slow)])  # a second draw: -m slow
def test_sigint_at_a_random_moment(tmp_path: Path, i: int) -> None:
    long_run = dataclasses.replace(ENDLESS, robots=2, seed=SEED)
    t = sigint_trial(long_run, tmp_path, np.random.default_rng([SEED, 2, i]), f"sigint{i}", window=5.0)
    _ok(t)
    assert t.exit_code == 130 and t.result["reason"] == "interrupted"


@pytest.mark.slow  # fuzz over processes; an attack over them by default
def test_fuzz_on_every_key_kills_nothing_and_changes_nothing(small_map: Path, tmp_path: Path) -> None:
    """Through an open router: the seeded result is the run's without fuzz (the memory engine's, every engine's
    for a seed)."""
    spec = _spec(small_map, max_ticks=100)
    code, _, err = run_cli(["run", *spec.args(), "--engine", "memory", "--no-record", "--quiet", "--out",
                            str(tmp_path / "base")])
    assert code in (0, 3), err
    t = fuzz_trial(spec, tmp_path, np.random.default_rng([SEED, 3]), "fuzz", 3000, None, result(tmp_path / "base"))
    _ok(t)  # "changed" included: the seeded result is the baseline's
    assert t.result["malformed_dropped"] > 0
    nodes = {"world", "netem", "r0", "r1", "r2"}
    assert set(t.result["malformed_dropped_by"]) >= nodes | {"launcher"}, t.result["malformed_dropped_by"]
    for name in nodes:  # each said so in its log (and none died: the trial's invariants)
        assert "dropped message" in (tmp_path / "fuzz" / f"{name}.log").read_text(), name
    assert "fleet: warning: --connect without --credentials" in (tmp_path / "fuzz.stderr").read_text()


@pytest.mark.slow  # fuzz over processes; an attack over them by default
def test_fuzz_from_a_robot_with_credentials_kills_nothing(small_map: Path, tmp_path: Path) -> None:
    t = fuzz_trial(_spec(small_map, max_ticks=100), tmp_path, np.random.default_rng([SEED, 4]), "fuzzauth", 2000,
                   "r1")
    _ok(t)
    assert t.result["authenticated"] is True


@pytest.mark.slow  # loss 0.9: every allocator on the memory engine by default
def test_loss_09_ends_by_the_tick_limit(small_map: Path, tmp_path: Path) -> None:
    """A protocol allocator (rounds of bids) over processes at loss 0.9: every invariant of a trial."""
    t = loss_trial(_spec(small_map, max_ticks=40), tmp_path, "trade", "loss-trade")
    _ok(t)
    assert t.result["ticks"] <= 40 and t.result["loss"] == 0.9


@pytest.mark.parametrize("allocator", allocator_names())
def test_loss_09_ends_by_the_tick_limit_for_every_allocator(small_map: Path, tmp_path: Path, allocator: str) -> None:
    """Every allocator at loss 0.9 reaches its target or the tick limit, or stalls: on the memory engine, since
    loss is netem's (the same Channel) and the lockstep messages are never lost, a processes run cannot end
    otherwise where this one ends (the trial above is one over processes)."""
    base = ["--base"] if allocator in BASE_PLANNERS else []
    code, _, err = run_cli(["run", *_spec(small_map, max_ticks=40).args(), "--allocator", allocator, "--loss", "0.9",
                            *base, "--engine", "memory", "--no-record", "--quiet", "--out", str(tmp_path / "run")])
    assert code in (0, 3), err
    res = result(tmp_path / "run")
    assert res["failed"] == [] and res["reason"] in ("coverage", "max_ticks", "stall")
    assert res["ticks"] <= 40 and res["loss"] == 0.9 and res["radio"]["dropped_loss"] > 0
