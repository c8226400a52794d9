"""The run's Zenoh router, in a process of its own (``python -m fleet_emu.launch.router_process SPEC``).

The launcher records and folds every message in Python. With the router in the same process, Zenoh's threads
that route the fleet's messages share the process (its runtime, its share of the 2 cores) with that work: at
256 robots with a recording the router stalled and the world failed every robot at a barrier. A router of its
own is what a fleet spread over machines has anyway (``zenohd``), so the processes engine always runs one; the
in-process engine, one process by design, keeps it embedded.

The child opens the router described by ``SPEC`` (a JSON file: ``listen`` endpoints, and optionally the users
file, the access control and the TLS identity), prints its endpoints as one JSON line, and runs until its
standard input closes: the launcher closes it to end the run, and a launcher killed outright closes it too, so
the router never outlives it. SIGTERM ends it as well.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import zenoh

from fleet_emu.core.access import Credential, Grant, acl_config, dictionary_text
from fleet_emu.core.bus import router_config, router_locators
from fleet_emu.core.errors import RunError
from fleet_emu.core.files import open_new

MODULE = "fleet_emu.launch.router_process"
READY_TIMEOUT = 30.0  # seconds for the child to open its router and print its endpoints
CLOSE_TIMEOUT = 10.0  # seconds for it to close once its standard input is closed, before SIGKILL


class RouterProcess:
    """A running router child: ``endpoints`` as it printed them, ``proc`` the child."""

    def __init__(self, proc: subprocess.Popen[bytes], endpoints: list[str]) -> None:
        self.proc = proc
        self.endpoints = endpoints

    def exited(self) -> int | None:
        """Its exit code once it has ended (it only ends when told, so any code during a run is a failure)."""
        return self.proc.poll()


@contextlib.contextmanager
def router_process(run_id: str, creds: dict[str, Credential] | None, listen: list[str],
                   tls: tuple[str, str] | None, log_dir: Path | None,
                   grants: tuple[tuple[Grant, ...], dict[str, str]] = ((), {})) -> Iterator[RouterProcess]:
    """Start the router child (user/password authentication and access control for this run's users, as
    :func:`fleet_emu.core.bus.router_config` embeds it), wait for its endpoints, and on the way out close it
    (its standard input, then SIGKILL to its group after :data:`CLOSE_TIMEOUT`). The users file lives in a
    private temporary directory only until the router has opened (Zenoh reads it then). Raises RunError with
    the child's own one-line reason when it cannot open."""
    log = log_dir / "router.log" if log_dir is not None else None
    with tempfile.TemporaryDirectory(prefix="fleet-router-") as private:  # mode 0700
        spec_file = Path(private) / "router.json"
        _write_private(spec_file, json.dumps(router_spec(Path(private), run_id, creds, listen, tls, grants)))
        err = open_new(log) if log is not None else None  # never through a link planted there; closed below
        try:
            proc = subprocess.Popen([sys.executable, "-m", MODULE, str(spec_file)],
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=err if err is not None else subprocess.DEVNULL, start_new_session=True)
        finally:
            if err is not None:
                err.close()
        try:
            endpoints = _read_endpoints(proc, log)
        except BaseException:
            _close(proc)
            raise
    try:
        yield RouterProcess(proc, endpoints)
    finally:
        _close(proc)


def router_spec(private: Path, run_id: str, creds: dict[str, Credential] | None, listen: list[str],
                tls: tuple[str, str] | None,
                grants: tuple[tuple[Grant, ...], dict[str, str]] = ((), {})) -> dict[str, Any]:
    """:func:`fleet_emu.core.bus.router_config`'s arguments for this run's router; with ``creds`` its users
    file is written (mode 0600) into the ``private`` directory, which the caller deletes once Zenoh has read it.
    ``grants``: access beyond the run's keys (:class:`~fleet_emu.core.access.Grant`) and the passwords of the
    users they add (``fleet run --ros2``'s viewer)."""
    spec: dict[str, Any] = {"listen": listen, "tls": tls}
    if creds is not None:
        users = private / "users.txt"
        _write_private(users, dictionary_text({n: c.password for n, c in creds.items()} | grants[1]))
        spec |= {"dictionary_file": str(users), "acl": acl_config(run_id, creds, grants[0])}
    return spec


def _write_private(path: Path, text: str) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(text)


def _read_endpoints(proc: subprocess.Popen[bytes], log: Path | None) -> list[str]:
    """The child's one JSON line; RunError with its reason when it exits or stays silent."""
    assert proc.stdout is not None
    deadline = time.monotonic() + READY_TIMEOUT
    line = b""
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([proc.stdout], [], [], left)[0]:
            raise RunError(f"cannot open the embedded Zenoh router: it did not start within {READY_TIMEOUT:g} s")
        chunk = os.read(proc.stdout.fileno(), 4096)
        if not chunk:
            proc.wait(timeout=CLOSE_TIMEOUT)
            raise RunError(f"cannot open the embedded Zenoh router: {_last_line(log) or f'exit {proc.returncode}'}")
        line += chunk
    return list(json.loads(line))


def _last_line(log: Path | None) -> str:
    with contextlib.suppress(OSError):
        if log is not None:
            lines = [s for s in log.read_text(errors="replace").splitlines() if s.strip()]
            return lines[-1].removeprefix("router: ") if lines else ""
    return ""


def _close(proc: subprocess.Popen[bytes]) -> None:
    """Close its standard input (the child closes its router and exits); SIGKILL its group if it lingers."""
    for pipe in (proc.stdin, proc.stdout):
        with contextlib.suppress(OSError):
            if pipe is not None:
                pipe.close()
    try:
        proc.wait(timeout=CLOSE_TIMEOUT)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


# --- the child ----------------------------------------------------------------------------------------------

def _terminate(*_: object) -> None:
    raise SystemExit(0)  # out of the blocking read below, through the session's close


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    signal.signal(signal.SIGTERM, _terminate)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the launcher decides when the router goes
    try:
        session = zenoh.open(router_config(**json.loads(Path(args[0]).read_text())))
    except (OSError, ValueError, TypeError, IndexError, zenoh.ZError) as exc:
        print(f"router: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", file=sys.stderr)
        return 1
    try:
        print(json.dumps(router_locators(session)), flush=True)
        with contextlib.suppress(OSError):
            while os.read(0, 4096):  # until the launcher closes our standard input (or dies)
                pass
    finally:
        with contextlib.suppress(zenoh.ZError):
            session.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
