"""``fleet export ros2`` writes a bag whole or not at all: into a hidden folder beside ``--out``, renamed once its
``metadata.yaml`` is written. A read-only folder and a full disk (real tmpfs mounts; skipped, saying so, where
mounting is not allowed) are one line and leave nothing; SIGINT and SIGTERM (real signals, sent to this process
from inside the export) leave nothing and a rerun works; rosbags (the library's reader) opens every bag that is
there. The recording is untrusted: a cut one is refused unless ``--partial``, a scenario that is a list is one
line."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

pytest.importorskip("rosbags")

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import run_memory
from fleet_emu.ros2.fold import Ros2Fold
from tests.harness.cli import run_cli
from tests.harness.files import crafted, tmpfs


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("whole") / "run"
    run_memory(Scenario().override(map="office", robots=3, seed=1, max_ticks=200), out, run_id="bagged")
    return out


def _opened(bag: Path) -> int:
    """The messages rosbags reads from ``bag``."""
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return sum(c.msgcount for c in reader.connections)


def _left(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.slow  # a second export; the bag's content by default (test_export)
def test_a_bag_is_renamed_whole_and_opens(recorded: Path, tmp_path: Path) -> None:
    code, out, err = run_cli(["export", "ros2", str(recorded), "--out", str(tmp_path / "bag")])
    assert code == 0, err
    assert _left(tmp_path) == ["bag"]  # no hidden folder left beside it
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag.mcap", "metadata.yaml"]
    assert _opened(tmp_path / "bag") == int(out.split(": ")[1].split()[0]) > 0


@pytest.mark.slow  # an export signalled; signals once by default
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_export_leaves_nothing_and_a_rerun_works(sig: signal.Signals, recorded: Path, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    fold = Ros2Fold.fold
    fed = [0]

    def interrupted(self: Ros2Fold, msg: object) -> list:
        fed[0] += 1
        if fed[0] == 500:  # mid-bag: the storage file is open, metadata.yaml not yet written
            os.kill(os.getpid(), sig)
        return fold(self, msg)  # type: ignore[arg-type]

    monkeypatch.setattr(Ros2Fold, "fold", interrupted)
    bag = tmp_path / "bag"
    code, _, err = run_cli(["export", "ros2", str(recorded), "--out", str(bag)])
    assert code == 128 + sig and "Traceback" not in err
    assert err.strip() == {signal.SIGINT: "fleet: interrupted", signal.SIGTERM: "fleet: terminated"}[sig], err
    assert fed[0] >= 500 and _left(tmp_path) == []  # neither the bag nor its hidden folder
    monkeypatch.setattr(Ros2Fold, "fold", fold)
    code, _, err = run_cli(["export", "ros2", str(recorded), "--out", str(bag)])
    assert code == 0, err
    assert _opened(bag) > 0


@pytest.mark.slow  # an export into a full disk; the bag's content by default
def test_a_full_disk_is_one_line_and_leaves_nothing(recorded: Path, tmp_path: Path) -> None:
    with tmpfs(tmp_path / "tiny", "64k") as disk:
        code, _, err = run_cli(["export", "ros2", str(recorded), "--out", str(disk / "bag")])
        assert code == 1 and err.count("\n") == 1 and "Traceback" not in err, err
        assert f"cannot write the bag {disk / 'bag'}: the disk is full" in err
        assert _left(disk) == []
    code, _, err = run_cli(["export", "ros2", str(recorded), "--out", str(tmp_path / "bag")])
    assert code == 0, err  # elsewhere, the same export works


def test_a_read_only_folder_is_one_line(recorded: Path, tmp_path: Path) -> None:
    with tmpfs(tmp_path / "ro", "1m") as disk:
        done = subprocess.run(["mount", "-o", "remount,ro", str(disk)], capture_output=True, text=True, timeout=30)
        if done.returncode != 0:
            pytest.skip(f"cannot remount read-only here: {done.stderr.strip()}")
        code, _, err = run_cli(["export", "ros2", str(recorded), "--out", str(disk / "bag")])
        assert code == 1 and err.count("\n") == 1 and "Traceback" not in err, err
        assert f"cannot write the bag {disk / 'bag'}: Read-only file system" in err
        assert _left(disk) == []


@pytest.mark.slow  # a second export; the bag's content by default (test_export)
def test_a_cut_recording_is_refused_unless_partial(recorded: Path, tmp_path: Path) -> None:
    half = tmp_path / "half"
    shutil.copytree(recorded, half)
    data = (recorded / "run.mcap").read_bytes()
    (half / "run.mcap").write_bytes(data[: len(data) // 2])
    whole = json.loads((recorded / "result.json").read_text())["recording"]["messages"]
    code, _, err = run_cli(["export", "ros2", str(half), "--out", str(tmp_path / "bag")])
    assert code == 2 and err.count("\n") == 1 and "run.mcap is cut:" in err and "--partial" in err, err
    assert not (tmp_path / "bag").exists() and _left(tmp_path) == ["half"]
    code, _, err = run_cli(["export", "ros2", str(half), "--out", str(tmp_path / "bag"), "--partial"])
    assert code == 0, err
    full = tmp_path / "full"
    assert run_cli(["export", "ros2", str(recorded), "--out", str(full)])[0] == 0
    assert 0 < _opened(tmp_path / "bag") < _opened(full)
    assert whole > 0


def test_a_scenario_that_is_a_list_is_one_line(tmp_path: Path) -> None:
    mcap = crafted(tmp_path / "list.mcap", [1, 2, 3])
    code, _, err = run_cli(["export", "ros2", str(mcap), "--out", str(tmp_path / "bag")])
    assert code == 2 and err.count("\n") == 1 and "is a JSON list, not a table" in err, err
    assert _left(tmp_path) == ["list.mcap"]
