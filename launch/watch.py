"""The launcher's watch over a run: a thread that records and folds what the bus brings, and the loop that
waits for the world's stop and the agents' reports, announcing robots whose processes exited and failing the
run when the world or netem dies."""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable

import zenoh

from fleet_emu.core.bus import Publisher, of_run
from fleet_emu.core.keys import BASE, Keys
from fleet_emu.core.messages import ready
from fleet_emu.launch.causes import froze, outside_stop, silent_world, state_timeout
from fleet_emu.launch.outdir import disk_fault
from fleet_emu.launch.router_process import RouterProcess
from fleet_emu.launch.supervisor import Supervisor
from fleet_emu.recording.foxglove_writer import FoxgloveWriter
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.recorder import FLUSH_SECONDS, Recorder

STOP_GRACE = 5.0


def wait_for_end(monitor: Monitor, consumer: Consumer, sup: Supervisor, nodes_thread: threading.Thread | None,
          on_progress: Callable[[Monitor], None] | None, requested: threading.Event,
          notify_failed: Callable[[str], None], router: RouterProcess | None = None,
          barrier_timeout: float | None = None) -> str | None:
    """Until the world's stop and every live agent's report; returns an error line, or None.
    An agent process that exits early is announced to the world, which goes on without it. The router's
    process (``router``) exiting, or the world or netem (or the base station) exiting with an error before
    the stop, fails the run at once; exiting cleanly
    (code 0) is a normal end whose stop message may still be on its way, so it fails the run only if no stop
    comes within :data:`STOP_GRACE` seconds of the launcher having folded every sample it received (with a
    hundred robots and more, their last belief snapshots can take the launcher longer than that). A stop this
    launcher did not send, or (with ``barrier_timeout``, the scenario's, in lockstep) a world silent for
    :func:`~fleet_emu.launch.causes.state_timeout` seconds, fails the run naming that cause, and a world that
    ended without a stop after a silence is named for it (:mod:`fleet_emu.launch.causes`)."""
    stop_seen: float | None = None
    pending_seen: float | None = None  # when a stop in the world's name came ahead of its tick's state
    clean_end: float | None = None
    announced: set[str] = set()
    while True:
        if on_progress is not None:
            on_progress(monitor)
        if consumer.fault is not None:  # the recording cannot be written (a full disk): nothing to wait for
            return consumer.fault
        if requested.is_set():
            return None
        if (cause := outside_stop(monitor)) is not None:
            return cause
        pending_seen = None if monitor.pending_stop is None else pending_seen or time.monotonic()
        if pending_seen is not None and not consumer.backlog() and time.monotonic() - pending_seen > STOP_GRACE:
            return outside_stop(monitor, pending=True)
        if barrier_timeout is not None and not consumer.backlog() and \
                (cause := silent_world(monitor, state_timeout(barrier_timeout))) is not None:
            return cause
        if monitor.stop is not None:
            stop_seen = stop_seen or time.monotonic()
            live = set(monitor.state.live) if monitor.state else set()
            reported = live <= set(monitor.reports) and (not monitor.base or monitor.base_report is not None
                                                          or BASE in sup.dead())
            if reported or time.monotonic() - stop_seen > STOP_GRACE:
                return None if monitor.stop.reason != "startup" else "startup timed out: see the logs in --out"
        if router is not None and (code := router.exited()) is not None:  # nothing can reach anyone now
            return f"the router process exited with code {code} (see router.log)"
        dead = sup.dead()
        new = set(dead) - announced - {"world", "netem", BASE}
        announced |= new
        if monitor.stop is None:  # repeated until the first tick: the world may not be listening yet
            for name in sorted(announced if monitor.state is None else new):
                notify_failed(name)
        if monitor.stop is None:
            for name in ("world", "netem", BASE):  # the base station is infrastructure: its death fails the run
                if dead.get(name, 0) != 0:
                    return f"the {name} process exited with code {dead[name]} (see {name}.log)"
            ended = [f"the {n} process exited with code 0" for n in ("world", "netem", BASE) if n in dead]
            if nodes_thread is not None and not nodes_thread.is_alive():
                ended.append("the in-process nodes ended")
            if ended:
                if clean_end is None or consumer.backlog():
                    clean_end = time.monotonic()  # the stop may be in the backlog still to fold (a large fleet)
                if time.monotonic() - clean_end > STOP_GRACE:
                    why = froze(monitor, barrier_timeout) if barrier_timeout is not None else None
                    return (f"{why}; then " if why else "") + \
                        f"{ended[0]} but no stop reached the launcher within {STOP_GRACE:g} s"
        consumer.changed.wait(0.2)
        consumer.changed.clear()


class Consumer(threading.Thread):
    """Takes samples off the subscriber's queue: records them, folds them, and answers the world's hello. The
    recording is flushed when the bus is quiet for a second; a recording that fails (a full disk) sets
    :attr:`fault`, the line the run ends with, and the fold goes on."""

    def __init__(self, keys: Keys, samples: queue.Queue, monitor: Monitor, recorder: Recorder | None,
                 pub_ready: Publisher, viz: FoxgloveWriter | None = None) -> None:
        super().__init__(daemon=True, name="recorder")
        self.keys = keys
        self.samples = samples
        self.monitor = monitor
        self.recorder = recorder
        self.viz = viz
        self.pub_ready = pub_ready
        self.changed = threading.Event()
        self.fault: str | None = None

    def backlog(self) -> int:
        """Samples received and not folded yet."""
        return self.samples.qsize()

    def run(self) -> None:
        while (item := self._next()) is not None:
            key, data, wall_ns = item
            if self.recorder is not None:
                self.recorder.record(key, data, wall_ns)
                self._check_recorder()
            parsed = self.keys.parse(key)
            if parsed is not None and parsed.channel == "hello":
                self.pub_ready.put(ready("launcher", "launcher", os.getpid()).encode())
                continue
            msg = self.monitor.feed(key, data, wall_ns)
            if self.viz is not None:
                self.viz.feed(key, data, wall_ns, msg)
            if msg is not None:
                self.changed.set()


    def _next(self) -> tuple[str, bytes, int] | None:
        """The next sample (None at the end); the recording flushed while none comes."""
        while True:
            try:
                item: tuple[str, bytes, int] | None = self.samples.get(timeout=FLUSH_SECONDS)
                return item
            except queue.Empty:
                if self.recorder is not None:
                    self.recorder.flush()
                    self._check_recorder()

    def _check_recorder(self) -> None:
        if self.recorder is not None and self.recorder.failed is not None and self.fault is None:
            self.fault = str(disk_fault(self.recorder.path.parent, self.recorder.failed, self.recorder.path.name))
            self.changed.set()


class Drain(threading.Thread):
    """One subscriber of the launcher's listener session, drained into the consumer's queue.

    Zenoh hands each sample to a FIFO channel in Rust, never to Python on its own threads: a Python callback
    there must take the GIL for every sample, and in this process (which also holds the embedded router) the
    Zenoh threads that wait for it stall the router's routing and its leases. At 256 robots a recording (every
    message, the first contacts' whole maps among them) made most robots' sessions expire that way.
    The thread ends when the subscriber is undeclared and its channel is empty. With ``nonce``, a sample that
    does not carry the run's nonce is neither recorded nor folded, only counted (:attr:`foreign`)."""

    CAPACITY = 1 << 20  # samples held before Zenoh waits for this thread (the queue behind it is unbounded)

    def __init__(self, session: zenoh.Session, key: str, samples: queue.Queue, nonce: bytes | None = None) -> None:
        super().__init__(daemon=True, name=f"drain {key}")
        self.subscriber = session.declare_subscriber(key, zenoh.handlers.FifoChannel(self.CAPACITY))
        self.samples = samples
        self.nonce = nonce
        self.foreign = 0
        self.start()

    def run(self) -> None:
        nonce = self.nonce
        for s in self.subscriber.handler:  # recv() waits without the GIL; ends once undeclared and empty
            if nonce is not None and not of_run(s, nonce):
                self.foreign += 1
                continue
            self.samples.put((str(s.key_expr), s.payload.to_bytes(), time.time_ns()))

    def undeclare(self) -> None:
        """Undeclare the subscriber and wait for what its channel still held."""
        with contextlib.suppress(zenoh.ZError):
            self.subscriber.undeclare()
        self.join(STOP_GRACE)
