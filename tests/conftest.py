"""What the whole suite shares: the drawn maps, the one finished run that several tests only read, the ``fleet``
CLI run as a user would (a subprocess) and in this process (:func:`run_cli`), and the helpers that watch a run's
processes. Test modules import these from here, never from one another."""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.harness.faults import RunSpec

ROOT = Path(__file__).resolve().parents[1]

#: A lockstep run that cannot end by itself while a test signals or kills it (``ENDLESS.args(robots=N)``: its
#: ``fleet run`` flags): a 1 m sensor on the maze at 10 cm cells. Three robots see a third of it in 2,000 ticks
#: (17 s on this machine), and only the whole of it or 100,000 ticks end the run. The office ends in 5 s with 2
#: or 3 robots, start-up included, so a signal a few seconds in can come after the run's own end.
ENDLESS = RunSpec("maze", max_ticks=100000, target_coverage=1.0, extra=("--cell-size", "0.1", "--sensor-range", "1"))

# A small two-room map (white free, black walls), drawn like the tests' ASCII grids.
TWO_ROOMS = """
########################
#..........#...........#
#..........#...........#
#......................#
#..........#...........#
#..........#...........#
####.#######.......#####
#..........#...........#
#..........#...........#
#......................#
#..........#...........#
########################
"""


def draw_map(ascii_map: str, path: Path) -> Path:
    """Save an ASCII grid (``#`` a wall, anything else free) as a greyscale PNG map: black walls, white floor."""
    rows = [ln.strip() for ln in ascii_map.strip().splitlines()]
    img = np.array([[0 if ch == "#" else 255 for ch in row] for row in rows], dtype=np.uint8)
    Image.fromarray(img, mode="L").save(path)
    return path


def pytest_configure(config: pytest.Config) -> None:
    """The suite starts a few hundred interpreters (fleets, CLIs, fork servers). They all load the kernels from the
    user's kernel cache, also those whose test gives them a user cache of their own (``XDG_CACHE_HOME``, for maps):
    ``FLEET_KERNEL_CACHE`` is set to it. Where ``PYTHONDONTWRITEBYTECODE`` keeps bytecode out of the tree, each
    would also compile the package from source again (about 0.2 CPU s): they share one bytecode cache in a folder
    of the session's instead (``PYTHONPYCACHEPREFIX``), and the tree stays as clean as the variable asks."""
    from fleet_emu.core.jit import cache_dir

    os.environ.setdefault("FLEET_KERNEL_CACHE", str(cache_dir()))
    if not os.environ.get("PYTHONDONTWRITEBYTECODE") or os.environ.get("PYTHONPYCACHEPREFIX"):
        return
    prefix = tempfile.mkdtemp(prefix="fleet-tests-pycache-")
    del os.environ["PYTHONDONTWRITEBYTECODE"]
    os.environ["PYTHONPYCACHEPREFIX"] = prefix
    config.add_cleanup(lambda: shutil.rmtree(prefix, ignore_errors=True))
    config.stash[_PYCACHE] = Path(prefix)


_PYCACHE = pytest.StashKey[Path]()
OWN = {"fleet_emu", "tests", "benchmarks"}  # the repository's modules: compiled by the children themselves


def _share_installed_bytecode(prefix: Path) -> int:
    """Link the installed bytecode of every module this process imported (the standard library, numpy, numba,
    zenoh...) into the children's bytecode cache, where each would otherwise be compiled from source once more
    (about 4 CPU s for the first interpreter that loads the kernels). The package's own modules are left to the
    children: this process wrote none. Returns how many were linked."""
    linked = 0
    for name, module in list(sys.modules.items()):
        cached, source = getattr(module, "__cached__", None), getattr(module, "__file__", None)
        if name.partition(".")[0] in OWN or not cached or not source or not os.path.isfile(cached):
            continue
        target = prefix / os.path.dirname(os.path.abspath(source)).lstrip(os.sep) / os.path.basename(cached)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            target.symlink_to(cached)
            linked += 1
        except OSError:
            pass
    return linked


@pytest.fixture(scope="session", autouse=True)
def _compiled_kernels(request: pytest.FixtureRequest) -> None:
    """Compile (or load) the numba kernels once, before any test: in a fresh checkout the cache is empty, and
    the first fleet's world, netem and fork server would each compile every kernel at once (three times the
    work of one compile); after this they all load the cached machine code. Then the children's bytecode
    cache, if this session made one, gets what this process has imported by then (a launcher's too)."""
    from fleet_emu.core.kernels import warm_up

    warm_up()
    prefix = request.config.stash.get(_PYCACHE, None)
    if prefix is not None:
        import fleet_emu.launch.runner  # (what a launcher imports besides the kernels)
        import fleet_emu.recording.live  # noqa: F401

        _share_installed_bytecode(prefix)


@pytest.fixture(scope="session")
def small_bitmap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """:data:`TWO_ROOMS` as ``two_rooms.png`` alone: a bare bitmap, read one pixel per cell at the cell size a
    run gives (the benchmarks that fit a map to a number of cells give theirs)."""
    return draw_map(TWO_ROOMS, tmp_path_factory.mktemp("maps") / "two_rooms.png")


@pytest.fixture(scope="session")
def small_map(small_bitmap: Path) -> Path:
    """``two_rooms.yaml``: the bitmap with its scale, 0.5 m per pixel (12 x 24 cells at the default cell size),
    so that a run needs no --cell-size."""
    path = small_bitmap.with_suffix(".yaml")
    path.write_text(f"image: {small_bitmap.name}\nresolution: 0.5\norigin: [0.0, 0.0, 0.0]\n")
    return path


@pytest.fixture(scope="session")
def small_run(small_map: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The suite's one plain finished run over processes, which tests only read: three robots on the two-room
    map (the default scenario otherwise: seed 0, 10 % loss, forked robots), recorded with the grid every 5
    ticks; ``run.mcap``, ``result.json`` and the logs in the returned directory."""
    out = tmp_path_factory.mktemp("run") / "small"
    run_cli(["run", "--map", str(small_map), "--robots", "3", "--quiet", "--grid-every", "5", "--out", str(out)],
            check=True)
    assert (out / "run.mcap").is_file() and (out / "result.json").is_file()
    return out


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
    """A run's ``result.json``, checked against its schema (``launch/schemas/result.schema.json``): every test
    that reads a run's result through here also proves the contract."""
    from fleet_emu.launch.result import validate_result

    data = json.loads((out / "result.json").read_text())
    validate_result(data)
    return data


def free_port() -> int:
    """A loopback port nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(predicate: Callable[[], object], timeout: float) -> None:
    """Poll ``predicate`` every 0.1 s; AssertionError after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting")
        time.sleep(0.1)


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is not alive
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def all_pids(res: dict) -> list[int]:
    """Every process of the run: world, netem, the agents, and the fork server, the router and the base (when
    there were)."""
    more = [res["pids"][k] for k in ("fork_server", "router", "base") if k in res["pids"]]
    return sorted({res["pids"]["world"], res["pids"]["netem"], *res["pids"]["agents"], *more})


def nothing_left(pids: Sequence[int], timeout: float = 15) -> None:
    """Wait until none of ``pids`` is alive (AssertionError after ``timeout`` seconds)."""
    wait_for(lambda: not any(pid_alive(p) for p in pids), timeout)


def children_of(pid: int) -> list[int]:
    """The direct children of ``pid``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if int((d / "stat").read_text().split(")")[-1].split()[1]) == pid:
                    found.append(int(d.name))
            except (OSError, ValueError, IndexError):
                pass
    return found


def _runs(pid: int, module: bytes) -> bool:
    try:
        return module in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def is_fork_server(pid: int) -> bool:
    """Whether a launcher's child is the robots' fork server (the robots it forks share its command line)."""
    return _runs(pid, b"fleet_emu.agents.forkserver")


def is_router(pid: int) -> bool:
    """Whether a launcher's child is the run's router process."""
    return _runs(pid, b"fleet_emu.launch.router_process")


def fleet_processes(launcher: int) -> list[int]:
    """The fleet's node processes under a launcher: its children but the fork server and the router, and the
    robots the fork server forked."""
    found = []
    for pid in children_of(launcher):
        if not is_router(pid):
            found += children_of(pid) if is_fork_server(pid) else [pid]
    return found


def make_certs(d: Path) -> tuple[Path, Path, Path]:
    """A CA, and a server certificate for localhost and 127.0.0.1 signed by it (rustls refuses a self-signed
    leaf): the paths of ``ca.pem``, ``cert.pem`` and ``key.pem`` in ``d``."""
    import datetime
    import ipaddress

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "fleet test CA")])
    ca = (x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(hours=1))
          .not_valid_after(now + datetime.timedelta(days=1))
          .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
          .sign(ca_key, hashes.SHA256()))
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")]))
            .issuer_name(ca_name).public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(hours=1)).not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName("localhost"),
                                                        x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                           critical=False)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .sign(ca_key, hashes.SHA256()))
    paths = d / "ca.pem", d / "cert.pem", d / "key.pem"
    paths[0].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    paths[1].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    paths[2].write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return paths


@contextlib.contextmanager
def tmpfs(mnt: Path, size: str):  # type: ignore[no-untyped-def]
    """A tmpfs of ``size`` (``mount -o size=``) mounted on ``mnt`` (made here), unmounted afterwards; a skip where
    mounting is not allowed."""
    mnt.mkdir()
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], capture_output=True,
                              text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"cannot mount a tmpfs here: {exc}")
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip() or done.returncode}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True, timeout=30)
