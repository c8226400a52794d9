"""Fault trials, shared by ``tests/integration/test_faults.py`` (a few) and
``benchmarks/fault_trials.py`` (hundreds).

Each trial runs the real ``fleet run`` CLI as a user would, does one harmful thing to it, and checks the
invariants every fault must keep (:class:`Trial`): the run ended by itself (no hang), ``result.json`` is there,
``run.mcap`` opens to the end with as many messages as ``result.json`` says, no process of the fleet is left
alive after the launcher exited (orphans), no node died but the one the trial killed (deaths: a failed robot, a
crashed world or netem, a traceback or a fatal error in a log), and the exit code is the one
docs/reference/errors.md gives.

- :func:`kill_trial`: ``kill -9`` of a random robot at a random tick (watched on an authenticated external
  router as the recorder user); exit 1, ``failed`` is exactly that robot.
- :func:`sigint_trial`: SIGINT (sometimes twice) at a random moment from the launch to the exit; exit 130.
- :func:`fuzz_trial`: fuzzed messages on every key (:mod:`fuzz`); through an unauthenticated router the
  seeded result must not change, through an authenticated one with a robot's credentials the run must end.
- :func:`loss_trial`: one allocator at loss 0.9 ends (its target, the tick limit or a stall), never hangs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import msgpack
import numpy as np
import zenoh
from mcap.reader import make_reader

from fleet_emu.core.access import Credential, read_dictionary
from fleet_emu.core.bus import client_config, router_config, router_locators
from fleet_emu.core.keys import Keys, robot_ids
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.router_config import router_config_text
from tests.harness.fuzz import fuzz_messages

ROOT = Path(__file__).resolve().parents[2]
HANG = 180.0  # seconds a run may take before the trial calls it hung
ORPHAN_GRACE = 5.0  # seconds the fleet's processes get to be gone after the launcher exited
CRASH_SIGNS = ("Traceback", "Fatal Python error", "Segmentation fault", "core dumped", "corrupted",
               "Bus error", "panicked", "Aborted")
VOLATILE = {"run_id", "pids", "recording", "decision_ms", "wall_seconds", "ticks_per_second", "robot_peak_rss_kb",
            "agent_peak_rss_kb", "malformed_dropped", "malformed_dropped_by", "authenticated"}


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """A short run: the ``fleet run`` flags of every trial."""

    map: str
    robots: int = 3
    max_ticks: int = 60
    target_coverage: float = 0.99
    seed: int = 0
    extra: tuple[str, ...] = ()

    def args(self, **override: Any) -> list[str]:
        spec = dataclasses.replace(self, **override)
        return ["--map", spec.map, "--robots", str(spec.robots), "--max-ticks", str(spec.max_ticks),
                "--target-coverage", str(spec.target_coverage), "--seed", str(spec.seed), *spec.extra]


@dataclasses.dataclass
class Trial:
    """What one trial saw, and which invariants it broke (:attr:`failures`)."""

    phase: str
    label: str = ""
    ended: bool = False
    exit_code: int | None = None
    expected_exit: tuple[int, ...] = (0, 3)
    result: dict | None = None
    recording_valid: bool = False
    orphans: int = 0
    deaths: list[str] = dataclasses.field(default_factory=list)
    changed: bool = False  # the seeded result differs from the baseline's (fuzz through an open router)
    notes: list[str] = dataclasses.field(default_factory=list)
    seconds: float = 0.0

    @property
    def wrong_exit(self) -> bool:
        return self.exit_code not in self.expected_exit

    @property
    def failures(self) -> list[str]:
        out = [] if self.ended else ["hung"]
        out += [] if self.result is not None else ["no result.json"]
        out += [] if self.recording_valid else ["invalid recording"]
        out += [f"{self.orphans} orphan(s)"] if self.orphans else []
        out += [f"death: {d}" for d in self.deaths]
        out += [f"exit {self.exit_code}, expected {'/'.join(map(str, self.expected_exit))}"] if self.wrong_exit else []
        out += ["result changed"] if self.changed else []
        return out


# --- processes ------------------------------------------------------------------------------------------------

def _stat(pid: int) -> tuple[int, int, str] | None:
    """(parent pid, start time, state) of a process, or None when it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return int(fields[1]), int(fields[19]), fields[0]


def _cmdline(pid: int) -> list[str]:
    try:
        return [a.decode(errors="replace") for a in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")]
    except OSError:
        return []


class Descendants(threading.Thread):
    """Every process below ``root`` seen while it ran, as (pid, start time), polled every 0.1 s."""

    def __init__(self, root: int) -> None:
        super().__init__(daemon=True, name="descendants")
        self.root = root
        self.seen: dict[int, int] = {}
        self.done = threading.Event()

    def scan(self) -> None:
        parents: dict[int, tuple[int, int]] = {}
        for d in Path("/proc").iterdir():
            if d.name.isdigit() and (st := _stat(int(d.name))) is not None:
                parents[int(d.name)] = (st[0], st[1])
        tree = {self.root} | set(self.seen)
        grew = True
        while grew:
            new = {p for p, (pp, _) in parents.items() if pp in tree and p not in tree}
            tree |= new
            grew = bool(new)
        for p in tree - {self.root}:
            if p in parents:
                self.seen.setdefault(p, parents[p][1])

    def run(self) -> None:
        while not self.done.wait(0.1):
            self.scan()

    def alive(self) -> list[int]:
        """The descendants still running (same pid and start time, not a zombie)."""
        out = []
        for pid, start in self.seen.items():
            st = _stat(pid)
            if st is not None and st[1] == start and st[2] != "Z":
                out.append(pid)
        return out

    def find(self, *words: str) -> int | None:
        """A live descendant whose command line holds every one of ``words``."""
        for pid in self.alive():
            args = _cmdline(pid)
            if all(w in args for w in words):
                return pid
        return None

    def find_robot(self, robot: str, run: str) -> int | None:
        """Robot ``robot``'s live process: started as ``python -m fleet_emu.agents --robot ROBOT --run RUN``, or
        forked by the fork server (its command line the server's, its name ``fleet ROBOT``; every descendant
        is of this run)."""
        for pid in self.alive():
            with contextlib.suppress(OSError):
                if Path(f"/proc/{pid}/comm").read_text().strip() == f"fleet {robot}":
                    return pid
        return self.find("fleet_emu.agents", robot, run)


@contextlib.contextmanager
def launched(args: list[str], out: Path, trial: Trial,
             hang: float = HANG) -> Iterator[tuple[subprocess.Popen, Descendants]]:
    """``fleet run ARGS --out OUT --quiet`` with its descendants watched; on leaving, wait for its end (a hang
    after ``hang`` s is SIGTERMed, then killed), count orphans and read what it left."""
    out.parent.mkdir(parents=True, exist_ok=True)
    stderr = out.parent / f"{out.name}.stderr"
    t0 = time.monotonic()
    with open(stderr, "wb") as err:
        proc = subprocess.Popen([sys.executable, "-m", "fleet_emu.launch", "run", *args, "--out", str(out), "--quiet"],
                                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err)
    watch = Descendants(proc.pid)
    watch.start()
    try:
        yield proc, watch
    finally:
        try:
            proc.wait(max(1.0, hang - (time.monotonic() - t0)))
            trial.ended = True
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        watch.done.set()
        watch.join()
        watch.scan()
        trial.seconds = time.monotonic() - t0
        trial.exit_code = proc.returncode
        deadline = time.monotonic() + ORPHAN_GRACE
        while watch.alive() and time.monotonic() < deadline:
            time.sleep(0.1)
        left = watch.alive()
        trial.orphans = len(left)
        for pid in left:  # the trial's own grandchildren: end them, by pid
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        _inspect(out, stderr, trial)


def _inspect(out: Path, stderr: Path, trial: Trial) -> None:
    """result.json, the recording, and the signs of a death in the logs."""
    with contextlib.suppress(OSError, ValueError):
        trial.result = json.loads((out / "result.json").read_text())
    trial.recording_valid = recording_valid(out / "run.mcap", trial.result)
    text = stderr.read_text(errors="replace")
    if any(s in text for s in CRASH_SIGNS):
        trial.deaths.append(f"launcher: {_sign(text)}")
    for log in sorted(out.glob("*.log")) if out.is_dir() else []:
        text = log.read_text(errors="replace")
        if any(s in text for s in CRASH_SIGNS):
            trial.deaths.append(f"{log.stem}: {_sign(text)}")
    if trial.result is not None and trial.result.get("reason") == "error":
        trial.deaths.append(f"run error: {trial.result.get('error')}")


def _sign(text: str) -> str:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return next((ln.strip() for ln in lines if any(s in ln for s in CRASH_SIGNS)), "?")[:160] + \
        (f" ... {lines[-1].strip()[:160]}" if lines else "")


def recording_valid(path: Path, res: dict | None) -> bool:
    """The MCAP reader opens it, reads every message to the end, and counts what result.json says."""
    if res is None or not path.exists():
        return False
    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            count = sum(1 for _ in reader.iter_messages())
            summary = reader.get_summary()
    except Exception:  # any way the reader fails is an invalid recording
        return False
    stats = sum(summary.statistics.channel_message_counts.values()) if summary and summary.statistics else -1
    return count == stats == res.get("recording", {}).get("messages")


def _check_failed(trial: Trial, expected: set[str]) -> None:
    failed = set(trial.result["failed"]) if trial.result else set()
    trial.deaths += [f"{r} failed" for r in sorted(failed - expected)]
    if expected - failed:
        trial.notes.append(f"killed {sorted(expected - failed)} not in result.json's failed")
        trial.expected_exit = (-1,)  # a kill the launcher did not see is a wrong outcome, whatever the code


def comparable(res: dict | None) -> dict:
    """What a seed reproduces on every engine (:func:`~fleet_emu.launch.result.deterministic`), less what the
    trials change on purpose (:data:`VOLATILE`): a baseline may come from the memory engine."""
    return {k: v for k, v in deterministic(res or {}).items() if k not in VOLATILE}


# --- routers the trials start --------------------------------------------------------------------------------

@contextlib.contextmanager
def auth_router(robots: int, work: Path) -> Iterator[tuple[str, Path]]:
    """An external router with the fleet's authentication and access control (`fleet router-config`)."""
    users = work / "users.txt"
    conf = zenoh.Config.from_json5(router_config_text(robots, users, listen="tcp/127.0.0.1:0"))
    conf.insert_json5("adminspace/enabled", "true")
    with zenoh.open(conf) as r:
        yield router_locators(r)[0], users


@contextlib.contextmanager
def open_router() -> Iterator[str]:
    """An external router anyone may join: no authentication, no access control."""
    with zenoh.open(router_config()) as r:
        yield router_locators(r)[0]


def login(endpoint: str, users: Path | None, user: str) -> zenoh.Session:
    cred = Credential(user, read_dictionary(users.read_text())[user]) if users is not None else None
    return zenoh.open(client_config(endpoint, cred))


class Ticks:
    """The world's tick and whether it stopped, from ``world/state`` (decoded loosely: this is a watcher)."""

    def __init__(self, session: zenoh.Session, run: str) -> None:
        self.tick = -1
        self.done = False
        self.nonce: bytes | None = None  # the run's, off its states' attachment (an open router shows it to all)
        self.changed = threading.Event()
        self._sub = session.declare_subscriber(Keys(run).state, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        if sample.attachment is not None:
            self.nonce = sample.attachment.to_bytes()
        with contextlib.suppress(Exception):
            obj = msgpack.unpackb(sample.payload.to_bytes())
            if isinstance(obj, dict) and obj.get("src") == "world" and isinstance(obj.get("tick"), int):
                self.tick = max(self.tick, obj["tick"])
                self.done = self.done or bool(obj.get("done"))
                self.changed.set()

    def wait(self, until: Callable[[], bool], proc: subprocess.Popen, timeout: float = HANG) -> bool:
        """Until ``until()``; False when the launcher exited or ``timeout`` passed first."""
        deadline = time.monotonic() + timeout
        while not until():
            if proc.poll() is not None or time.monotonic() > deadline:
                return False
            self.changed.wait(0.05)
            self.changed.clear()
        return True

    def close(self) -> None:
        with contextlib.suppress(zenoh.ZError):
            self._sub.undeclare()


# --- the trials ------------------------------------------------------------------------------------------------

def kill_trial(spec: RunSpec, work: Path, rng: np.random.Generator, run: str, window: int | None = None) -> Trial:
    """``kill -9`` of a random robot when the world reaches a random tick in ``[0, window)`` (default: up to 10
    ticks before the tick limit; the target coverage should be out of reach so that the run gets there)."""
    victim = str(rng.choice(robot_ids(spec.robots)))
    at = int(rng.integers(0, window or max(1, spec.max_ticks - 10)))
    trial = Trial("kill -9 robot", f"{victim} at tick {at}", expected_exit=(1,))
    with auth_router(spec.robots, work) as (endpoint, users), login(endpoint, users, "recorder") as s:
        ticks = Ticks(s, run)
        args = [*spec.args(), "--connect", endpoint, "--credentials", str(users), "--run-id", run]
        with launched(args, work / run, trial) as (proc, watch):
            if ticks.wait(lambda: ticks.tick >= at or ticks.done, proc) and not ticks.done:
                pid = watch.find_robot(victim, run)
                if pid is None:
                    watch.scan()
                    pid = watch.find_robot(victim, run)
                if pid is not None:
                    os.kill(pid, signal.SIGKILL)
                    trial.label += f" (killed at tick {ticks.tick})"
                else:
                    trial.notes.append(f"no process for {victim}")
            else:
                trial.notes.append("the run ended before the kill tick")
        ticks.close()
    killed = set() if trial.notes else {victim}
    if not killed:
        trial.expected_exit = (0, 3)
    _check_failed(trial, killed)
    return trial


def sigint_trial(spec: RunSpec, work: Path, rng: np.random.Generator, run: str, window: float) -> Trial:
    """SIGINT at a random moment in ``[0, window)`` seconds after the launch (the embedded router), and with
    probability 0.3 a second one up to a second later; exit 130 unless the launcher had already exited."""
    delay = float(rng.uniform(0, window))
    second = float(rng.uniform(0, 1.0)) if rng.random() < 0.3 else None
    trial = Trial("SIGINT", f"at {delay:.2f} s" + (f", again {second:.2f} s later" if second is not None else ""),
                  expected_exit=(130,))
    sent_at = None
    with launched([*spec.args(), "--run-id", run], work / run, trial) as (proc, _):
        try:
            proc.wait(delay)
            trial.expected_exit = (0, 3)
            trial.notes.append("the launcher exited before the signal")
        except subprocess.TimeoutExpired:
            sent_at = time.time()
            proc.send_signal(signal.SIGINT)
            if second is not None:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(second)
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
    _check_failed(trial, set())
    written = work / run / "result.json"
    if trial.result is not None and trial.result.get("signal") is None and sent_at is not None and \
            written.stat().st_mtime <= sent_at:  # the run had ended and written its files: the exit is its own
        trial.expected_exit = (0, 3)
        trial.notes.append("the signal came after result.json was written")
    if trial.result is not None and trial.expected_exit == (130,) and trial.result.get("signal") != "SIGINT":
        trial.notes.append(f"result.json signal is {trial.result.get('signal')!r}")
        trial.expected_exit = (-1,)
    return trial


def loss_trial(spec: RunSpec, work: Path, allocator: str, run: str, loss: float = 0.9) -> Trial:
    """One allocator under heavy loss: it reaches its target or the tick limit (or stalls), never hangs."""
    trial = Trial(f"loss {loss:g}", allocator)
    with launched([*spec.args(), "--allocator", allocator, "--loss", str(loss), "--run-id", run], work / run, trial):
        pass
    _check_failed(trial, set())
    if trial.result is not None:
        trial.label += f": {trial.result['reason']} at tick {trial.result['ticks']}"
        if trial.result["reason"] not in ("coverage", "max_ticks", "stall"):
            trial.expected_exit = (-1,)
    return trial


def fuzz_trial(spec: RunSpec, work: Path, rng: np.random.Generator, run: str, n: int, as_robot: str | None = None,
               baseline: dict | None = None) -> Trial:
    """``n`` fuzzed messages on every key of a run, sent from its first tick on with the run's nonce (read off
    its states, as any subscriber can: the fuzz is for the decoders behind the nonce). Through an open router
    (``as_robot`` None) with ``baseline`` given, the result must equal the baseline's (nothing was accepted);
    through an authenticated one, logged in as ``as_robot``, the run must still end without a death."""
    trial = Trial("fuzz " + (f"as {as_robot} (auth)" if as_robot else "(open router)"), f"{n} messages")
    with contextlib.ExitStack() as stack:
        if as_robot is None:
            endpoint, users, extra = stack.enter_context(open_router()), None, []
        else:
            endpoint, users = stack.enter_context(auth_router(spec.robots, work))
            extra = ["--credentials", str(users)]
        s = stack.enter_context(login(endpoint, users, as_robot) if as_robot else zenoh.open(client_config(endpoint)))
        ticks = Ticks(s, run)
        sent = during = 0
        kinds: dict[str, int] = {}
        with launched([*spec.args(), "--connect", endpoint, *extra, "--run-id", run], work / run, trial) as (proc, _):
            if ticks.wait(lambda: ticks.tick >= 0, proc):
                for key, data, mutation in fuzz_messages(rng, run, robot_ids(spec.robots), n, as_robot):
                    s.put(key, data, congestion_control=zenoh.CongestionControl.BLOCK, attachment=ticks.nonce)
                    sent += 1
                    during += not ticks.done
                    kinds[mutation] = kinds.get(mutation, 0) + 1
            ticks.close()
        trial.label += f", {during} before the stop"
        if during < n:
            trial.notes.append(f"only {during} of {n} fuzzed messages reached the run before it stopped")
    _check_failed(trial, set())
    if trial.result is not None:
        trial.label += f", {trial.result.get('malformed_dropped', 0)} dropped by the nodes"
    if baseline is not None and trial.result is not None:
        diff = sorted(k for k in set(comparable(baseline)) | set(comparable(trial.result))
                      if comparable(baseline).get(k) != comparable(trial.result).get(k))
        trial.changed = bool(diff)
        if diff:
            trial.notes.append(f"differs from the baseline in {diff}")
    return trial


def plain_trial(spec: RunSpec, work: Path, run: str, connect_open: bool = False) -> Trial:
    """A run with no fault (the baseline of the SIGINT window and of the open-router fuzz)."""
    trial = Trial("no fault", "open router" if connect_open else "embedded router")
    with contextlib.ExitStack() as stack:
        extra = ["--connect", stack.enter_context(open_router())] if connect_open else []
        with launched([*spec.args(), *extra, "--run-id", run], work / run, trial):
            pass
    _check_failed(trial, set())
    return trial
