"""A sweep survives its disk: on a real tmpfs that fills up mid-sweep (mounting needs root: skipped, saying so,
where it cannot be mounted), the sweep ends in one line with exit 1, naming its failed runs, writing the tables
that fit and keeping no recording a reader cannot open; resumed once space is freed, it has a row for every
point. A row cut mid-line is detected on resume and its point runs again; a resume never reports success with a
point missing."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.recording.recover import is_whole
from fleet_emu.sweep.execute import ROWS, read_rows
from fleet_emu.sweep.study import Study
from tests.harness.cli import run_cli
from tests.harness.files import tmpfs


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A mounted 2 MB tmpfs, unmounted after the test."""
    with tmpfs(tmp_path / "disk", "2m") as mnt:
        yield mnt


def _kept(study_dir: Path) -> Path:
    text = (study_dir / "tiny.toml").read_text().replace('baseline = "nearest"', 'baseline = "nearest"\nrecord = "all"')
    (study_dir / "kept.toml").write_text(text)
    return study_dir / "kept.toml"


def test_a_full_disk_ends_a_sweep_in_one_line_and_a_resume_completes_it(study_dir: Path, small_disk: Path) -> None:
    study = _kept(study_dir)
    ballast = small_disk / "ballast"
    ballast.write_bytes(b"\0" * (1600 << 10))  # 400 kB left: a few runs' recordings, not eight
    out = small_disk / "out"
    code, _, err = run_cli(["sweep", str(study), "--out", str(out), "--jobs", "1", "--quiet"])
    assert code == 1, err
    errors = [line for line in err.splitlines() if line.startswith("fleet:")]
    assert len(errors) == 1 and "Traceback" not in err, err
    assert errors[0].startswith(f"fleet: error: cannot write the sweep's files in {out}: ") and \
        "No space left on device" in errors[0], err
    rows = read_rows(out)
    failed = [r["id"] for r in rows if r["status"] != "ok"]
    assert failed and all(i in errors[0] for i in failed)
    assert (out / "results.csv").is_file() or "results.csv" in errors[0]  # what fits is written
    for r in rows:  # a recording the sweep names opens
        if r.get("run_dir"):
            assert is_whole(out / r["run_dir"] / "run.mcap"), r
    for folder in (out / "runs").iterdir():
        assert any(r.get("run_dir") == f"runs/{folder.name}" for r in rows), folder  # none kept unnamed

    ballast.unlink()
    code, _, err = run_cli(["sweep", str(study), "--out", str(out), "--jobs", "1", "--quiet"])
    assert code == 0, err
    ids = {p.id for p in Study.load(study).points(None)}
    assert {r["id"] for r in read_rows(out)} == ids and all(r["status"] == "ok" for r in read_rows(out))


def test_a_row_cut_mid_line_runs_again_and_a_missing_point_is_never_success(study_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--jobs", "1", "--quiet"])
    assert code == 0, err
    lines = (out / ROWS).read_bytes().splitlines(keepends=True)
    cut = json.loads(lines[-1])["id"]
    (out / ROWS).write_bytes(b"".join(lines[:-1]) + lines[-1][:40])  # the disk took 40 bytes of the last row
    assert cut not in {r["id"] for r in read_rows(out)}
    code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--jobs", "1"])
    assert code == 0, err
    assert "8 rows of 8 points (0 failed)" in err and "ran 1 of 1" in err
    assert cut in {r["id"] for r in read_rows(out)}  # the row appended after the cut one is whole



def test_a_sweep_with_a_point_without_a_row_is_not_a_success(study_dir: Path, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """A row that never reached the file (a disk that lost it) is counted against the grid: never exit 0."""
    from fleet_emu.sweep import execute

    write = execute.RowWriter.write
    lost: list[str] = []

    def lossy(self: execute.RowWriter, row: dict[str, Any]) -> None:
        if not lost:
            lost.append(row["id"])
            return
        write(self, row)

    monkeypatch.setattr(execute.RowWriter, "write", lossy)
    out = tmp_path / "out"
    code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--jobs", "1", "--quiet"])
    assert code == 201, err
    assert f"1 points have no row: {lost[0]}" in err
