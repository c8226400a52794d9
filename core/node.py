"""What every node shell shares: counted drops of malformed messages, the ready handshake, liveliness.

The node shells (world, netem, agents) are the only code that touches Zenoh; they build on this.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import os
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, Protocol, TypeVar

import zenoh

from fleet_emu.core.access import Credential, allowed_src
from fleet_emu.core.bus import Inbox, Publisher, client_config, publisher
from fleet_emu.core.codec import Context, DecodeError, Message, decode
from fleet_emu.core.errors import FleetError
from fleet_emu.core.fields import cell_arg
from fleet_emu.core.grid import MapData
from fleet_emu.core.keys import Keys
from fleet_emu.core.malloc_tuning import collect_less, keep_heap
from fleet_emu.core.messages import Hello, ready
from fleet_emu.core.scenario import Scenario

M = TypeVar("M", bound=Message)

log = logging.getLogger("fleet")


class NodeShell:
    """The shell every node class extends (world, netem, robot, base station): a node of one run, its id, its
    keys, a drop counter and the answer to the world's hello; the I/O around a node's functional core."""

    role: str = "node"

    def __init__(self, keys: Keys, node_id: str) -> None:
        self.keys = keys
        self.node_id = node_id
        self.dropped = 0
        self._seq = 0
        self.nonce: bytes | None = None  # the run's nonce (:meth:`bind`): on every put, checked on every message
        self._inboxes: list[Inbox] = []

    def bind(self, nonce: bytes | None) -> NodeShell:
        """Bind the node to its run's nonce (the launcher's ``--nonce``): its messages carry it, and a message
        without it is dropped and counted (:attr:`foreign`). Without a nonce nothing is checked."""
        self.nonce = nonce
        return self

    def publisher(self, session: zenoh.Session, key_expr: str) -> Publisher:
        """A publisher of this node's run: every put carries the run's nonce."""
        return publisher(session, key_expr, self.nonce)

    def inbox(self) -> Inbox:
        """The node's inbox: a message of another nonce is dropped and counted there."""
        inbox = Inbox(nonce=self.nonce)
        self._inboxes.append(inbox)
        return inbox

    @property
    def foreign(self) -> int:
        """Messages dropped so far for carrying another run's nonce (or none)."""
        return sum(i.foreign for i in self._inboxes)

    async def run(self, session: zenoh.Session) -> object:
        """The node's whole run on ``session`` (each shell's own)."""
        raise NotImplementedError

    def next_seq(self) -> int:
        """The node's one sequence counter (deterministic for a seed). The start handshake (hello, ready),
        repeated until answered as timing goes, carries seq 0 and does not draw from it."""
        self._seq += 1
        return self._seq

    def decode(self, key: str, data: bytes, expected: type[M], ctx: Context | None = None) -> M | None:
        """Decode or count-and-drop: a malformed message is never fatal, and neither is one whose ``src`` may
        not write on its key (the second line of defence behind the router's access control)."""
        try:
            msg = decode(data, ctx, expected)
        except DecodeError as exc:
            self.drop(key, str(exc))
            return None
        return msg if self.may_write(key, msg.src) else None

    def may_write(self, key: str, src: str) -> bool:
        """Whether ``src`` may write on ``key``; a message from anyone else is counted and dropped."""
        parsed = self.keys.parse(key)
        allowed = allowed_src(parsed) if parsed is not None else frozenset()
        if allowed is not None and src not in allowed:
            self.drop(key, f"{src!r} may not write on this key")
            return False
        return True

    def drop(self, key: str, why: str) -> None:
        self.dropped += 1
        if self.dropped <= 5 or self.dropped % 100 == 0:
            log.warning("%s %s: dropped message #%d on %s: %s", self.role, self.node_id, self.dropped, key, why)

    def declare_presence(self, session: zenoh.Session, inbox: Inbox) -> list[Declared]:
        """Subscribe to the hello, then declare the liveliness token (after every other subscription)."""
        self._ready_pub = self.publisher(session, self.keys.ready(self.node_id))
        sub = inbox.subscribe(session, self.keys.hello)
        token = session.liveliness().declare_token(self.keys.alive(self.role, self.node_id))
        return [self._ready_pub, sub, token]

    def answer_hello(self, key: str, data: bytes) -> None:
        if self.decode(key, data, Hello) is not None:
            self._ready_pub.put(ready(self.node_id, self.role, os.getpid()).encode())


class Declared(Protocol):
    """A subscriber, publisher or liveliness token: something a session declared and must undeclare."""

    def undeclare(self) -> None: ...


D = TypeVar("D", bound=Declared)


def undeclare(handles: list[D]) -> None:
    """Undeclare explicitly, newest first (dropping the Python object does not undeclare a callback subscriber
    in zenoh-python 1.10); a session already closing is not an error."""
    for handle in reversed(handles):
        with contextlib.suppress(zenoh.ZError):
            handle.undeclare()
    handles.clear()


def setup_logging() -> None:
    """One-line warnings on stderr for every process."""
    logging.basicConfig(stream=sys.stderr, level=logging.WARNING, format="%(name)s: %(message)s")


async def watch_parent(period: float = 0.5) -> None:
    """Exit the process when the launcher that spawned it dies (no orphan is left behind)."""
    parent = os.getppid()
    while True:
        await asyncio.sleep(period)
        if os.getppid() != parent:
            log.warning("launcher %d is gone; exiting", parent)
            os._exit(3)


async def run_node(node_coro: Awaitable[object], watch: bool = True) -> None:
    """Run a node's coroutine with the parent watchdog beside it."""
    watchdog = asyncio.create_task(watch_parent()) if watch else None
    try:
        await node_coro
    finally:
        if watchdog is not None:
            watchdog.cancel()


def parse_child(parser: argparse.ArgumentParser, argv: list[str] | None, map_file: bool = False) -> argparse.Namespace:
    """The command line every child process takes: ``--run``, ``--connect``, ``--scenario FILE.json``
    (written by ``fleet run``), for the world and netem ``--map-file MAP.npz`` (the launcher's one build of
    the true map), and ``--auth-stdin`` (the credential comes on standard input, never on the command line or
    in the environment, where other users could read it), and ``--realtime HZ`` in a real-time run. A bad
    file is one line on stderr and exit code 2."""
    parser.add_argument("--run", required=True, help="run id (the <run> of the key expressions)")
    parser.add_argument("--connect", required=True, help="router endpoint, e.g. tcp/127.0.0.1:7447")
    parser.add_argument("--scenario", required=True, type=Path, help="scenario as JSON (written by fleet run)")
    if map_file:
        parser.add_argument("--map-file", required=True, type=Path, help="the true map (written by fleet run)")
    parser.add_argument("--realtime", type=float, default=None, metavar="HZ",
                        help="real-time mode: the world ticks at HZ on the wall clock (default: lockstep)")
    parser.add_argument("--auth-stdin", action="store_true",
                        help="read this process's bus credential (one JSON line) from standard input")
    parser.add_argument("--nonce", type=_nonce_arg, default=None, metavar="HEX",
                        help="the run's nonce (drawn by fleet run): put on every message, and a message without "
                             "it is dropped (default: none, nothing checked)")
    args = parser.parse_args(argv)
    try:
        args.scenario = Scenario.from_json(args.scenario)
        if map_file:
            args.map_file = MapData.load(args.map_file)
        args.credential = Credential.from_json(sys.stdin.readline()) if args.auth_stdin else None
    except (OSError, ValueError, KeyError, FleetError) as exc:
        print(f"{parser.prog}: error: bad input file: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    return args


def _nonce_arg(text: str) -> bytes:
    """An argparse type: a run nonce in hex."""
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected hex digits, got {text!r}") from None


def add_base_cell(parser: argparse.ArgumentParser, required: bool) -> None:
    """``--base-cell ROW,COL``: the base station's cell, for netem (a radio endpoint there; none without the
    flag) and the base station's process. The launcher resolves it once (``world.build.base_cell``: with
    ``base = true`` it is the world's start cell, a ``random`` one drawn by the world) and passes it on, since
    these processes do not import the world's code."""
    parser.add_argument("--base-cell", type=cell_arg, required=required, default=None, metavar="ROW,COL",
                        help="the base station's cell (resolved by fleet run)")


def node_main(prog: str, build: Callable[[argparse.Namespace], Any], argv: list[str] | None,
              extra: Callable[[argparse.ArgumentParser], object] | None = None, map_file: bool = False) -> None:
    """The ``__main__`` of a node process: parse the child command line, build the node, open one client
    session to the router, and run the node with the parent watchdog beside it."""
    parser = argparse.ArgumentParser(prog=prog)
    if extra is not None:
        extra(parser)
    args = parse_child(parser, argv, map_file)
    setup_logging()
    keep_heap()  # the same map-sized arrays every tick: no page faults for them (core/malloc_tuning.py)
    collect_less()  # and the many small decoded messages of a tick not scanned again and again
    try:
        node = build(args).bind(args.nonce)
    except FleetError as exc:  # arguments that do not fit together (the launcher's, or a hand-made run's)
        print(f"{prog}: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    with zenoh.open(client_config(args.connect, args.credential)) as session:
        asyncio.run(run_node(node.run(session)))
