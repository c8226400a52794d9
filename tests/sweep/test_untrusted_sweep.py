"""Peers and grids a sweep does not trust: a "scheduler" that accepts TCP and never answers (a real socket on the
loopback) is refused within the handshake's deadline instead of hanging ``fleet sweep`` (the Dask client waits
without one), and a grid over :data:`MAX_POINTS` runs is refused from the lengths of its lists, saying how many
runs it would be, before a single point is built."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.study import MAX_POINTS, Study
from tests.harness.cli import ROOT, fleet
from tests.harness.peers import silent_peer
from tests.harness.procs import wait_for

pytest.importorskip("distributed")


def test_a_peer_that_accepts_and_stays_silent_is_refused_within_the_deadline() -> None:
    from fleet_emu.sweep.execute import connect_dask

    with silent_peer() as address, pytest.raises(ConfigError, match="no Dask scheduler answered within 1 s"):
        connect_dask(address, seconds=1.0)


def test_fleet_sweep_on_a_silent_scheduler_ends_with_one_line(study_dir: Path) -> None:
    """The adversary's own command: ``fleet sweep --dask`` at the silent peer, which hung for 240 s and more;
    now the promised 10 s handshake (the subprocess's own timeout is the test's deadline)."""
    with silent_peer() as address:
        proc = fleet("sweep", str(study_dir / "tiny.toml"), "--dask", address, "--out", str(study_dir / "out"),
                     check=False, timeout=60)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "no Dask scheduler answered within 10 s" in proc.stderr
    assert not (study_dir / "out").exists()


def _as_in_a_terminal() -> None:
    """SIGINT at its default, as in a terminal's foreground (a shell's background job starts with it ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow  # signals over processes: the sigint trial by default
def test_ctrl_c_ends_the_wait_on_a_silent_scheduler(study_dir: Path) -> None:
    """SIGINT once the sweep waits on the silent peer's handshake (it holds a connection): the command ends at
    once as interrupted, well before the handshake's 10 s (a deadline on the test, not a timing)."""
    accepted: list[socket.socket] = []
    with silent_peer(accepted) as address:
        proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "sweep", str(study_dir / "tiny.toml"), "--dask",
                                 address, "--out", str(study_dir / "out")], cwd=ROOT, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True, preexec_fn=_as_in_a_terminal)
        try:
            wait_for(lambda: accepted or proc.poll() is not None, 60)
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=5)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    assert proc.returncode == 130 and "interrupted" in err, err


def test_a_grid_over_the_limit_is_refused_saying_how_many_runs() -> None:
    grid = {f"k{i}": list(range(10)) for i in range(10)}  # 10^10 points: expanding them would never end
    with pytest.raises(ConfigError, match=r"10,000,000,000 runs \(10 k0 x .* x 10 k9 x 1 seeds\)"):
        Study.from_dict({"study": {"name": "huge"}, "grid": grid})
    with pytest.raises(ConfigError, match="1,000,000,000 runs"):
        Study.from_dict({"study": {"name": "seeds", "seeds": 10**9}, "grid": {"robots": [2]}})
    just = Study.from_dict({"study": {"name": "ok", "seeds": MAX_POINTS // 2}, "grid": {"robots": [2, 3]}})
    assert len(just.seeds) * 2 == MAX_POINTS
