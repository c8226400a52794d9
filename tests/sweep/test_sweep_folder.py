"""A sweep's ``--out`` is locked as a run's is: a second sweep into a folder another process holds is refused
naming its pid, before anything is written there."""

from __future__ import annotations

import os
from pathlib import Path

from fleet_emu.launch.outdir import lock_folder
from tests.harness.cli import run_cli


def test_a_sweep_into_a_held_folder_is_refused_naming_the_holder(study_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "results"
    out.mkdir()
    held = lock_folder(out)  # a second open file description: flock refuses it as it would another process
    try:
        code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--quiet"])
    finally:
        held.release()
    assert code == 2 and err.count("\n") == 1, err
    assert f"in use by another run (pid {os.getpid()})" in err
    assert os.listdir(out) == []  # nothing written, and the lock file gone with its holder
