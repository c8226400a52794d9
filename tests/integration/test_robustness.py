"""Bad input (in this process through the CLI's ``main``, and twice through the console script's real exit) and
a killed router — with real processes (teardown on Ctrl-C and on a killed launcher: ``test_forkserver.py``; a
killed robot, and malformed traffic on every key through an open router: ``test_faults.py``)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.harness.cli import ENDLESS, ROOT, fleet, result, run_cli
from tests.harness.procs import all_pids, children_of, free_port, is_router, pid_alive, wait_for


class Toml(str):
    """A scenario file's text in a bad-input row: the test writes it to a file and passes that file's path."""


def _one_line(code: int, err: str, match: str) -> None:
    """Refused with exit 2 and one line, ``fleet: error: ...`` containing ``match``, and no traceback."""
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fleet: error:") and match in lines[0], err
    assert "Traceback" not in err


@pytest.mark.parametrize("args, match", [
    (["--map", "/no/such/map.png"], "not found"),
    (["--map", "nowhere"], "unknown map"),
    (["--robots", "0"], "robots"),
    (["--robots", "257"], "--robots must be from 1 to 256 (got 257)"),
    (["--loss", "1.5"], "loss"),
    (["--sensor-range", "-2"], "sensor-range"),
    (["--sensor-range", "inf"], "--sensor-range must be a finite number"),
    (["--sensor-range", "nan"], "--sensor-range must be a finite number"),
    (["--comm-range", "-1"], "comm-range"),
    (["--comm-range", "inf"], "--comm-range must be a finite number"),
    (["--cell-size", "inf"], "--cell-size must be a finite number"),
    (["--allocator", "telepathy"], "telepathy"),
    (["--robots", "three"], "invalid int"),
    (["--scenario", "/no/such.toml"], "not found"),
    (["/no/such.toml"], "not found"),
    (["a.toml", "--scenario", "b.toml"], "two scenarios given (a.toml and --scenario b.toml): give one"),
    (["a.toml", "b.toml"], "unrecognized arguments: b.toml"),
    (["--out", "/proc/forbidden"], "--out /proc/forbidden: cannot write there"),
    (["--out", "/proc/forbidden/deeper/still"], "cannot write there"),
    (["--run-id", "a/b"], "--run-id must be"),
    (["--run-id", "*"], "--run-id must be"),
    (["--run-id", "../up"], "--run-id must be"),
    (["--connect", "notanendpoint"], "--connect 'notanendpoint' is not a Zenoh endpoint"),
    (["--connect", f"tcp/127.0.0.1:{free_port()}"], "no Zenoh router answered (gave up after 5 s)"),
    (["--scenario", Toml('[fleet]\nrobots = "four"')], "bad.toml: [fleet] robots must be a whole number"),
    (["--scenario", Toml('[radio]\nloss = "high"')], "bad.toml: [radio] loss must be a finite number"),
    (["--scenario", Toml('[fleet]\nsensor_range = "4"')], "bad.toml: [fleet] sensor_range must be a finite number"),
    (["--scenario", Toml("seed = 1.5")], "bad.toml: seed must be a whole number"),
    (["--scenario", Toml('map = "office"')], "'map' must be a [map] section, not a value"),
])
def test_bad_input_is_one_line_and_nonzero(args: list[str], match: str, tmp_path: Path) -> None:
    for i, arg in enumerate(args):
        if isinstance(arg, Toml):
            (tmp_path / "bad.toml").write_text(arg + "\n")
            args = [*args[:i], str(tmp_path / "bad.toml"), *args[i + 1:]]
    out = tmp_path / "x"
    code, _, err = run_cli(["run", "--out", str(out), *args, "--quiet"])  # a later --out wins
    _one_line(code, err, match)
    assert not out.exists() and not Path("/proc/forbidden").exists()  # refused before any file was written
    assert not (ROOT / "runs" / "a").exists() and not (ROOT / "up").exists()


def test_bad_input_exits_2_from_the_console_script(tmp_path: Path) -> None:
    """The real exit path of a refusal by the parser: a new interpreter, its exit code, its stderr (the
    refusal of a value the parser accepted, after the run's imports: ``test_bad_input_without_quiet...``)."""
    proc = fleet("run", "--robots", "three", "--out", str(tmp_path / "x"), "--quiet", check=False, timeout=60)
    _one_line(proc.returncode, proc.stderr, "argument --robots: invalid int value: 'three'")
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("args, env, match", [
    (["--robots", "250"], {}, "250 robots do not fit the free area reachable from the start cell"),
    (["--robots", "100", "--no-fork-server"], {"FLEET_MEM_AVAILABLE_MB": "4000"},
     r"100 robots \(each started afresh\) need about \d+\.\d GB of memory \(robots .*\) but 3\.9 GB is "
     r"available \(MemAvailable, or FLEET_MEM_AVAILABLE_MB\); run fewer robots, or with the fork server$"),
    (["--robots", "100", "--engine", "memory"], {"FLEET_MEM_AVAILABLE_MB": "100"},
     r"100 robots \(on the memory engine\) need about \d+ MB of memory .* but 100 MB is available"),
    (["--robots", "2"], {"FLEET_MEM_AVAILABLE_MB": "lots"}, "FLEET_MEM_AVAILABLE_MB must be a number of MB"),
])
def test_a_fleet_the_map_or_the_machine_cannot_hold_is_refused(args: list[str], env: dict[str, str], match: str,
                                                              small_map: Path, tmp_path: Path) -> None:
    """Before anything starts: more robots than the map's free area, or than the memory available (faked with
    FLEET_MEM_AVAILABLE_MB; the same fleet with the fork server fits)."""
    out = tmp_path / "x"
    where = ["--map", str(small_map)] if "250" in args else []
    code, _, err = run_cli(["run", *where, *args, "--out", str(out), "--quiet"], env=env)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fleet: error: ") and re.search(match, lines[0]), err
    assert not out.exists()


def test_bad_input_without_quiet_is_still_one_line(tmp_path: Path) -> None:
    proc = fleet("run", "--run-id", "a b", "--out", str(tmp_path / "x"), check=False, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "fleet: error: --run-id must be letters, digits, '_', '-' or '.' (not first), at most 100 (got 'a b')"]
    assert not (tmp_path / "x").exists()


def test_a_sensor_range_beyond_the_map_is_clamped(small_map: Path, tmp_path: Path) -> None:
    """On the memory engine: the same World and Brain objects the node processes run."""
    out = tmp_path / "run"
    code, _, err = run_cli(["run", "--sensor-range", "1e9", "--map", str(small_map), "--robots", "2",
                            "--max-ticks", "30", "--out", str(out), "--quiet", "--engine", "memory", "--no-record"])
    assert code in (0, 3), err[-2000:]
    assert "Traceback" not in err
    res = result(out)
    assert res["scenario"]["sensor_range"] == 1e9 and res["failed"] == []
    assert res["coverage"] > 0.9  # two rooms and a door: the first scans see most of the map


@pytest.mark.parametrize("section, match", [
    ('type = "minpos"\nwavefront = "fastest"', "allocator 'minpos': wavefront must be one of"),
    ('type = "minpos"\nwavefronts = "stop"', "allocator 'minpos' has no parameter 'wavefronts'"),
    ('type = "connectivity"\nlam = "high"', "allocator 'connectivity': lam must be a finite number within [0, 1]"),
    ('type = "hungarian"\ntimeout = true', "allocator 'hungarian': timeout must be a whole number >= 1"),
])
def test_bad_allocator_parameter_in_a_scenario(section: str, match: str, tmp_path: Path) -> None:
    scenario = tmp_path / "bad.toml"
    scenario.write_text(f"[allocator]\n{section}\n")
    allocator = section.split('"')[1]
    code, _, err = run_cli(["run", "--scenario", str(scenario), "--allocator", allocator, "--out",
                            str(tmp_path / "x"), "--quiet"])
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"fleet: error: scenario {scenario}: {match}"), err
    assert not (tmp_path / "x").exists()  # refused before any process started


def test_unparseable_map_file(tmp_path: Path) -> None:
    bad = tmp_path / "garbage.png"
    bad.write_bytes(b"this is not a png")
    code, _, err = run_cli(["run", "--map", str(bad), "--cell-size", "0.5", "--quiet", "--out", str(tmp_path / "x")])
    assert "cannot read image" in err
    assert code == 2 and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def _start(out: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "fleet_emu.launch", "run", *ENDLESS.args(robots=3), "--out", str(out), "--quiet",
         *extra],
        cwd=ROOT, stderr=subprocess.PIPE, text=True)


def test_a_killed_router_fails_the_run_keeps_the_recording_and_leaves_nothing_behind(tmp_path: Path) -> None:
    """The router runs in its own process: when it dies nothing reaches anyone, so the run ends at once as an
    error, with its files written and every process gone."""
    out = tmp_path / "run"
    proc = _start(out)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    routers = [p for p in children_of(proc.pid) if is_router(p)]
    assert len(routers) == 1
    os.kill(routers[0], signal.SIGKILL)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err[-2000:]
    assert err.strip().splitlines()[-1] == "fleet: error: the router process exited with code -9 (see router.log)"
    assert "Traceback" not in err
    res = result(out)
    assert res["reason"] == "error" and res["pids"]["router"] == routers[0]
    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and sum(summary.statistics.channel_message_counts.values()) == \
        res["recording"]["messages"] > 0
    wait_for(lambda: not any(pid_alive(p) for p in all_pids(res)), 15)
