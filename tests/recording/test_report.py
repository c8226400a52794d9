"""``fleet report``: the metrics fold on hand-made messages, a real run's report against its result.json, the
plots, ``--compare``, cut recordings and bad input."""

from __future__ import annotations

import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.records import Chunk
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import Writer
from PIL import Image

from fleet_emu.agents.protocol import PoseBeacon
from fleet_emu.core.errors import ReportError
from fleet_emu.core.grid import from_ascii
from fleet_emu.core.messages import (
    Command,
    Links,
    Observation,
    RadioMsg,
    Ready,
    RxBundle,
    Stop,
    TxBundle,
    WorldState,
    seal,
)
from fleet_emu.recording.metrics import DEPRECATED_GROUPS, NOT_RECORDED, RunMetrics, gini, jain
from fleet_emu.recording.plots import PLOTS
from fleet_emu.recording.read import load_recording
from fleet_emu.recording.report import write_report
from fleet_emu.recording.result import validate_metrics
from tests.harness.cli import ROOT, run_cli

ART = """
#######
#.....#
#.#...#
#.....#
#######
"""


# --- the pure fold ----------------------------------------------------------------------------------------------

def test_jain_and_gini() -> None:
    assert jain([1, 1, 1]) == pytest.approx(1.0)
    assert jain([3, 0, 0]) == pytest.approx(1 / 3)
    assert gini([2, 2]) == pytest.approx(0.0)
    assert gini([0, 0, 5]) == pytest.approx(2 / 3)
    assert jain([0, 0]) is None and gini([]) is None


def _scenario() -> dict:
    return {"robots": 2, "cell_size": 0.5, "map": "art", "seed": 3, "allocator": {"type": "minpos"},
            "radio": {"loss": 0.1, "comm": "wall", "threshold": 0.0}, "target_coverage": 0.99, "belief_every": 0}


def test_metrics_fold_on_hand_made_messages() -> None:
    truth, _ = from_ascii(ART)
    m = RunMetrics(_scenario(), "run-x")

    def feed(key: str, msg) -> None:
        m.feed(f"fleet/run-x/{key}", msg.encode(), 1_000_000_000 + msg.tick * 10_000_000)

    def obs(robot: str, tick: int, cell: tuple[int, int], cells: list[int]) -> Observation:
        c = np.array(cells, np.int32)
        return Observation(src="world", tick=tick, seq=0, robot=robot, cell=cell, shape=truth.shape, cell_size=0.5,
                           cells=c, values=truth.ravel()[c].astype(np.int8))

    def links(tick: int, linked: bool) -> Links:
        link = np.array([[False, linked], [linked, False]])
        return Links(src="netem", tick=tick, seq=0, robots=("r0", "r1"), strength=np.full((2, 2), 3.0, np.float32),
                     link=link, connected=linked, sent=4 * (tick + 1), delivered=3, dropped_loss=1,
                     dropped_signal=4 * tick, bytes_sent=len(beacon.encode()), bytes_by={"r0": len(beacon.encode())})

    beacon = seal(RadioMsg(PoseBeacon(cell=(1, 1))), "r0", 0, 0)  # the one emission: its envelope counts
    feed("ctl/ready/r0", Ready(src="r0", tick=0, seq=0, role="agent", pid=11))
    feed("world/obs/r0", obs("r0", 0, (1, 1), [8, 9, 15]))
    feed("world/obs/r1", obs("r1", 0, (3, 5), [9, 19, 26]))
    feed("world/state", WorldState(src="world", tick=0, seq=0, poses={"r0": (1, 1), "r1": (3, 5)},
                                   live=("r0", "r1"), coverage=0.5, path_length={"r0": 0, "r1": 0}))
    feed("netem/links", links(0, True))
    tx0 = TxBundle(src="r0", tick=0, seq=0, msgs=(beacon,))
    feed("radio/tx/r0", tx0)
    feed("radio/tx/r1", TxBundle(src="r1", tick=0, seq=0, msgs=()))
    feed("robot/r0/cmd", Command(src="r0", tick=0, seq=0, move=(0, 1), target=(1, 5), decision_ms=1.0))
    feed("robot/r1/cmd", Command(src="r1", tick=0, seq=0, move=(0, 0), target=None, decision_ms=2.0))
    feed("world/obs/r0", obs("r0", 1, (1, 2), [26]))
    feed("world/obs/r1", obs("r1", 1, (3, 5), [10]))
    feed("world/state", WorldState(src="world", tick=1, seq=0, poses={"r0": (1, 2), "r1": (3, 5)},
                                   live=("r0", "r1"), coverage=0.95, path_length={"r0": 1, "r1": 0}, done=True,
                                   reason="max_ticks"))  # the world's last state says it is done, then it stops
    feed("netem/links", links(1, False))
    feed("radio/rx/r1", RxBundle(src="netem", tick=1, seq=0, dst="r1", msgs=(beacon,)))
    feed("robot/r0/cmd", Command(src="r0", tick=1, seq=0, move=(0, 0), target=None, decision_ms=3.0))
    feed("ctl/stop", Stop(src="world", tick=1, seq=0, reason="max_ticks"))
    m.feed("fleet/run-x/radio/tx/r1", b"\x93garbage", None)  # undecodable: counted, never raised

    r = m.metrics("x.mcap")
    assert r["ticks"] == 1 and r["coverage"] == 0.95 and r["t90"] == 1 and r["t99"] is None
    assert r["reason"] == "max_ticks" and r["connected_fraction"] == 0.5
    assert r["t100"] is None
    assert r["path"] == {"per_robot": {"r0": 1, "r1": 0}, "total": 1}
    assert r["efficiency"]["value"] == 6.0  # six free cells sensed, one cell travelled
    assert r["overlap"]["cells"] == 2 and r["overlap"]["team_cells_sensed"] == 6
    assert r["overlap"]["fraction"] == pytest.approx(1 / 3, abs=1e-6)
    # cell 9 was first sensed by both at tick 0 (half each); 26 by r1 at tick 0, before r0 at tick 1
    assert r["share"]["credit"] == {"r0": 2.5, "r1": 3.5}
    assert r["share"]["jain"] == pytest.approx(36 / 37, abs=1e-6)
    assert r["share"]["gini"] == pytest.approx(1 / 12, abs=1e-6)
    assert r["connectivity"]["pair_link_fraction"] == {"r0-r1": 0.5}
    rd = r["radio"]
    assert rd["sent"] == 8 and (rd["dropped_loss"], rd["dropped_signal"]) == (1, 4) and rd["by_kind"] == {"pose": 1}
    assert rd["per_robot"]["r0"]["msgs_sent"] == 1 and rd["per_robot"]["r0"]["bytes_sent"] == len(beacon.encode())
    assert rd["per_robot"]["r1"]["msgs_received"] == 1
    dt = r["decision_ms"]
    assert dt["calls"] == 3 and dt["mean"] == 2.0 and dt["per_robot_mean"] == {"r0": 2.0, "r1": 2.0}
    assert r["pids"]["robots"] == [11, None] and r["undecodable"] == 1
    assert r["recording"] == {"path": "x.mcap", "messages": 17}
    # the first layout's groups, written beside for one release: each old key reads its quantity's one name
    assert r["exploration_time"] == {"t90": 1, "t99": None, "t100": None}
    assert r["radio_detail"]["dropped"] == {"loss": 1, "signal": 4} and r["decision_time"]["mean_ms"] == 2.0
    for group, keys in DEPRECATED_GROUPS.items():
        for old, new in keys.items():
            assert _at(r[group], old) == _at(r, new), (group, old, new)


def _at(data: dict[str, Any], dotted: str) -> Any:
    """``data``'s value at a dotted key (``radio.dropped_loss``)."""
    for part in dotted.split("."):
        data = data[part]
    return data


# --- a real run -------------------------------------------------------------------------------------------------

@pytest.fixture(scope="session")
def reported(small_run: Path) -> tuple[str, dict]:
    """``fleet report`` of the suite's plain run: what it printed, and its ``metrics.json``."""
    code, out, err = run_cli(["report", str(small_run)])
    assert code == 0, err
    return out, json.loads((small_run / "metrics.json").read_text())


def test_report_metrics_equal_result_json(small_run: Path, reported) -> None:
    printed, metrics = reported
    live = json.loads((small_run / "result.json").read_text())
    for key, value in live.items():
        if key in NOT_RECORDED:  # the launcher's clock and signals: not on the bus
            assert key not in metrics
        elif key == "pids":  # the world sends no Ready; netem and every agent do
            assert metrics[key]["robots"] == value["robots"] and metrics[key]["netem"] == value["netem"]
        elif key in ("radio", "decision_ms"):  # one name for a quantity: the report's groups add to the run's
            assert {k: metrics[key][k] for k in value} == value, key
        else:
            assert metrics[key] == value, key
    for extra in ("t100", "path", "efficiency", "overlap", "share", "connectivity"):
        assert extra in metrics
    assert metrics["path"]["total"] == sum(live["path_length"])
    assert metrics["decision_ms"]["calls"] == live["robots"] * live["ticks"]
    validate_metrics(metrics)  # metrics.schema.json over result.schema.json
    assert "matches result.json" in printed and "coverage" in printed


def colours(png: Path) -> int:
    """How many distinct colours an image has (a blank plot has one or two)."""
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(np.uint32)
    return len(np.unique((rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]))


def test_plots_are_written_and_not_blank(small_run: Path, reported) -> None:
    for name in PLOTS:
        path = small_run / f"{name}.png"
        assert path.stat().st_size > 5_000, name
        assert colours(path) > 4, name


def test_compare(small_run: Path, reported, tmp_path: Path) -> None:
    out = tmp_path / "cmp.png"
    code, printed, err = run_cli(["report", "--compare", str(small_run), str(small_run / "run.mcap"), "--out",
                                  str(out)])
    assert code == 0, err
    assert "comparison" in printed and printed.count("minpos") >= 2
    assert out.stat().st_size > 5_000
    assert colours(out) > 4


# --- cut recordings -------------------------------------------------------------------------------------------

def flushed(data: bytes) -> list[tuple[int, int]]:
    """(end offset, messages up to it) after each chunk (or loose message) of a recording."""
    bio = io.BytesIO(data)
    out, n = [], 0
    try:
        for rec in StreamReader(bio, emit_chunks=True).records:
            if isinstance(rec, Chunk):
                n += sum(isinstance(r, McapMessage) for r in breakup_chunk(rec))
            elif isinstance(rec, McapMessage):
                n += 1
            else:
                continue
            out.append((bio.tell(), n))
    except Exception:  # a cut file ends inside a record
        pass
    return out


def _ticks_flushed(mcap: Path) -> int:
    try:
        return load_recording(mcap, partial=True).metrics["ticks"]
    except ReportError:  # not there yet, or nothing flushed yet
        return 0


@pytest.fixture(scope="session")
def killed_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An in-process run (every node in the launcher) killed with SIGKILL after a few flushes."""
    out = tmp_path_factory.mktemp("killed") / "run"
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu.launch", "run", "--map", "office", "--robots", "3",
                             "--quiet", "--in-process", "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline and proc.poll() is None:
            if _ticks_flushed(out / "run.mcap") >= 20:
                break
            time.sleep(0.2)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    assert not (out / "result.json").exists(), "the run ended before it was killed"
    return out


@pytest.mark.slow  # a fleet killed for it; a killed run recovered by default (test_run_folder)
def test_killed_run_reports(killed_run: Path, tmp_path: Path) -> None:
    """The report recovers the cut recording first (``fleet recover``), then reads the whole one."""
    run_dir = tmp_path / "run"
    shutil.copytree(killed_run, run_dir)  # the session's cut run stays cut for the other tests
    data = (run_dir / "run.mcap").read_bytes()
    code, printed, err = run_cli(["report", str(run_dir), "--no-plots"])
    assert code == 0, err
    assert "rewritten whole" in printed and (run_dir / "run.mcap.cut").read_bytes() == data
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["truncated"] is False
    assert metrics["recording"]["messages"] == flushed(data)[-1][1] > 0
    assert metrics["ticks"] > 0 and metrics["coverage"] > 0 and metrics["decision_ms"]["calls"] > 0
    assert json.loads((run_dir / "result.json").read_text())["reason"] == "crashed"


# killed: a fleet killed for it (2.6 CPU s), slow; test_run_folder recovers a killed run by default
@pytest.mark.parametrize("which", ["small", pytest.param("killed", marks=pytest.mark.slow)])
def test_cut_copies_read_every_flushed_message(which: str, small_run: Path, request: pytest.FixtureRequest,
                                               tmp_path: Path) -> None:
    run = small_run if which == "small" else request.getfixturevalue("killed_run")
    data = (run / "run.mcap").read_bytes()
    ends = flushed(data)
    assert ends
    offsets = {8, 9, 100, len(data) // 3, len(data) // 2, len(data) - 1, len(data)}
    offsets |= {e + d for e, _ in ends for d in (-1, 0, 1) if 8 <= e + d <= len(data)}
    cut = tmp_path / "cut.mcap"
    for off in sorted(offsets):
        cut.write_bytes(data[:off])
        expected = max((n for e, n in ends if e <= off), default=0)
        try:
            run = load_recording(cut, partial=True)
        except ReportError as exc:  # cut before the first flush: nothing to read, one line for the user
            assert expected == 0 and "cut before" in str(exc), off
            continue
        assert run.messages == expected, off
        assert run.truncated == (off < len(data) or which == "killed")
        if run.truncated:  # without partial=True a cut recording is refused, saying how much of it reads
            with pytest.raises(ReportError, match=f"is cut: {expected} messages read, \\d+ of its {off} bytes"):
                load_recording(cut)
    written = write_report(run, plots=False)
    assert written["metrics"] == tmp_path / "cut.metrics.json" and written["metrics"].is_file()


# --- bad input ------------------------------------------------------------------------------------------------

def test_missing_path_is_one_line_exit_2(tmp_path: Path) -> None:
    code, _, err = run_cli(["report", str(tmp_path / "nope")])
    assert code == 2
    assert err.startswith("fleet: error: ") and err.count("\n") == 1
    assert "Traceback" not in err


def _no_scenario(path: Path) -> None:
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        ch = w.register_channel(topic="x", message_encoding="msgpack", schema_id=0)
        w.add_message(ch, 0, b"\x80", 0)
        w.finish()


@pytest.mark.parametrize("case", ["text", "empty", "dir", "no_scenario", "compare_out", "out_alone"])
def test_bad_input(case: str, tmp_path: Path, small_run: Path) -> None:
    args = ["report"]
    if case == "text":
        (tmp_path / "a.mcap").write_text("hello\n")
        args.append(str(tmp_path / "a.mcap"))
    elif case == "empty":
        (tmp_path / "a.mcap").write_bytes(b"")
        args.append(str(tmp_path / "a.mcap"))
    elif case == "dir":
        args.append(str(tmp_path))
    elif case == "no_scenario":
        _no_scenario(tmp_path / "a.mcap")
        args.append(str(tmp_path / "a.mcap"))
    elif case == "compare_out":
        args += ["--compare", str(small_run), "--out", str(tmp_path / "missing" / "c.png")]
    else:
        args += [str(small_run), "--out", str(tmp_path / "c.png")]
    code, _, err = run_cli(args)
    assert code == 2
    assert err.startswith("fleet: error: ") and err.count("\n") == 1, err


def test_panels_plot_draws_a_panel_per_key_and_a_line_per_series(tmp_path: Path) -> None:
    """The small multiples of ``benchmarks/paper_setting.py`` (Fig. 7): rows and columns from the keys."""
    from fleet_emu.recording.plots import panels_plot

    out = tmp_path / "panels.png"
    panels = {("grid", "mhm"): {"10 robots": [1, 5, 9], "20 robots": [1, 8, 20]},
              ("grid", "minpos"): {"10 robots": [1, 2]}, ("cave", "mhm"): {"10 robots": [3, 4, 4, 6]}}
    panels_plot(panels, out, xlabel="tick", ylabel="cells seen", title="t")
    with Image.open(out) as im:
        two_by_two = im.size
    assert out.stat().st_size > 5_000 and colours(out) > 4
    panels_plot({("grid", "mhm"): panels[("grid", "mhm")]}, out, xlabel="tick", ylabel="cells seen", title="t")
    with Image.open(out) as im:
        one = im.size
    assert two_by_two[0] > 1.5 * one[0] and two_by_two[1] > 1.5 * one[1]  # 2 columns, 2 rows against 1 x 1
