"""The ``fleet`` CLI as the tests run it: as a user would (a subprocess, :func:`fleet`) and in this process
(:func:`run_cli`), a run's ``result.json`` read through its schema (:func:`result`), and :data:`ENDLESS`, the run
that does not end by itself while a test signals or kills it."""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from tests.harness.faults import RunSpec

ROOT = Path(__file__).resolve().parents[2]

#: A lockstep run that cannot end by itself while a test signals or kills it (``ENDLESS.args(robots=N)``: its
#: ``fleet run`` flags): a 1 m sensor on the maze at 10 cm cells. Three robots see a third of it in 2,000 ticks
#: (17 s on this machine), and only the whole of it or 100,000 ticks end the run. The office ends in 5 s with 2
#: or 3 robots, start-up included, so a signal a few seconds in can come after the run's own end.
ENDLESS = RunSpec("maze", max_ticks=100000, target_coverage=1.0, extra=("--cell-size", "0.1", "--sensor-range", "1"))


def fleet(*args: str, timeout: float = 240, check: bool = True, env: dict[str, str] | None = None,
          cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    """Run the ``fleet`` CLI as a user would (``python -m fleet_emu`` is the console script's module);
    ``env``: variables set on top of this process's environment. With ``check``, an exit other than 0 or 3
    fails the test."""
    proc = subprocess.run([sys.executable, "-m", "fleet_emu", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, env={**os.environ, **env} if env else None)
    if check and proc.returncode not in (0, 3):
        raise AssertionError(f"fleet {' '.join(args)} exited {proc.returncode}:\n{proc.stderr[-3000:]}")
    return proc


def run_cli(argv: Sequence[str], env: dict[str, str] | None = None, cwd: Path = ROOT,
            check: bool = False) -> tuple[int, str, str]:
    """The ``fleet`` CLI's ``main(argv)`` in this process: ``(exit code, stdout, stderr)``. The same code as the
    console script up to the exit (``tests/integration/test_robustness.py`` runs that exit path for real),
    without a new interpreter's start-up and imports: a hundred times cheaper for input that is refused before
    anything starts, and a run's launcher here (its fleet's processes are still its own). ``env``: variables
    set for the call; the signal handlers, the environment and the working directory are put back after it.
    Any exception but the CLI's ``SystemExit`` propagates (a traceback fails the test); with ``check``, an exit
    other than 0 or 3 fails it too."""
    from fleet_emu.cli import main  # the one place the suite names the CLI's module

    out, err = io.StringIO(), io.StringIO()
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    saved = {k: os.environ.get(k) for k in env or {}}
    here = Path.cwd()
    try:
        os.environ.update(env or {})
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            main(list(argv))
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        os.chdir(here)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    if check and code not in (0, 3):
        raise AssertionError(f"fleet {' '.join(argv)} exited {code}:\n{err.getvalue()[-3000:]}")
    return code, out.getvalue(), err.getvalue()


def result(out: Path) -> dict:
    """A run's ``result.json``, checked against its schema (``recording/result.schema.json``): every test
    that reads a run's result through here also proves the contract."""
    from fleet_emu.launch.result import validate_result

    data = json.loads((out / "result.json").read_text())
    validate_result(data)
    return data
