"""``fleet run --ros2 [DOMAIN]``: the run's topics (:mod:`.fold`) published in rmw_zenoh's format
(:mod:`.rmw`) on the run's own router, so ``ros2 topic list``, ``ros2 topic echo`` and rviz2 with
``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` see the fleet without a bridge process.

The bridge is a companion of the launcher (:data:`fleet_emu.launch.runner.Companion`): its own Zenoh session,
logged in as the launcher (whose grants let it put on ``<domain>/**`` and declare ``@ros2_lv/<domain>/**``
tokens), subscribed to the run's keys it folds. Zenoh hands it samples through a ring channel that drops the
oldest when it falls behind, and its thread does the folding and publishing: the fleet's lockstep never waits on
it, and a run's result is the same with and without it. One node, ``/fleet_emu``, declares one publisher per topic
(their liveliness tokens before the fleet starts, so the topics are listed at once). Latched topics (the grids)
are published through Zenoh's advanced publisher with a cache of one sample, as rmw_zenoh does for transient
local: a late subscriber's query gets the last grid.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import secrets
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import zenoh

from fleet_emu.core.access import LAUNCHER, Grant, dictionary_text
from fleet_emu.core.bus import client_config, of_run
from fleet_emu.core.codec import decode
from fleet_emu.core.errors import DecodeError, RunError
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import Message
from fleet_emu.launch.runner import BusAccess, Companion
from fleet_emu.ros2 import rmw
from fleet_emu.ros2.fold import Out, Ros2Fold, topics
from fleet_emu.ros2.types import cdr, type_hash

log = logging.getLogger(__name__)

NODE = "fleet_emu"
VIEWER = "ros2"  # the read-only login a ROS 2 viewer gets on an authenticated router
RING = 1 << 16  # samples the bridge may fall behind before Zenoh drops the oldest for it
_ALL = ("put", "delete", "declare_subscriber", "query", "declare_queryable", "reply", "liveliness_token",
        "declare_liveliness_subscriber", "liveliness_query")


def grants(domain: int) -> tuple[Grant, ...]:
    """The embedded router's access for ROS 2 (docs/design/security.md): the launcher may publish on the
    domain's keys, answer queries there (the latched topics' caches) and declare the graph's liveliness tokens;
    the viewer may subscribe, query and declare its own tokens (rmw_zenoh's subscriptions announce themselves),
    and is sent everything on those keys. It may put nothing: no one but the launcher writes the topics."""
    # ``@adv`` is a verbatim chunk (the advanced publishers' caches and tokens): ``**`` never matches it
    keys = (f"{domain}/**", f"{domain}/**/@adv/**", f"{rmw.ADMIN_SPACE}/{domain}/**")
    viewer_in = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query", "query",
                 "liveliness_token")
    return (
        Grant(LAUNCHER, ("ingress",), ("put", "declare_queryable", "reply", "liveliness_token"), keys),
        Grant(LAUNCHER, ("egress",), ("declare_subscriber", "query", "liveliness_query",
                                      "declare_liveliness_subscriber"), keys),
        Grant(VIEWER, ("ingress",), viewer_in, keys),
        Grant(VIEWER, ("egress",), _ALL, keys),
    )


@dataclasses.dataclass(frozen=True)
class Ros2Options:
    """``--ros2``: the ROS domain, the viewer's password on an authenticated router (None: the bus has no
    logins), and who is told the line ``ros2: ENDPOINT domain N [credentials FILE]``."""

    domain: int = 0
    viewer_password: str | None = None
    say: Callable[[str], None] = lambda line: print(line, file=sys.stderr, flush=True)

    @classmethod
    def new(cls, domain: int, authenticated: bool) -> Ros2Options:
        return cls(domain, secrets.token_urlsafe(24) if authenticated else None)

    def companion(self) -> Companion:
        return lambda access: bridge(access, self)

    def run_options(self) -> dict[str, Any]:
        """The ``RunOptions`` fields of a bridged run: the companion, and on the run's own (authenticated)
        router the grants and the viewer's login."""
        options: dict[str, Any] = {"companions": (self.companion(),)}
        if self.viewer_password is not None:
            options |= {"grants": grants(self.domain), "grant_users": {VIEWER: self.viewer_password}}
        return options


@contextlib.contextmanager
def bridge(access: BusAccess, opts: Ros2Options) -> Iterator[Bridge]:
    """The bridge, open for the run (the launcher enters it once its router is up)."""
    try:
        b = Bridge(access, opts.domain)
    except zenoh.ZError as exc:
        raise RunError(f"--ros2: cannot publish on the run's router: {str(exc).splitlines()[0]}") from None
    try:
        line = f"ros2: {access.endpoint} domain {opts.domain}"
        if access.login is not None and opts.viewer_password is not None:
            line += f" credentials {write_viewer(access.work / 'ros2.users', opts.viewer_password)}"
        opts.say(line)
        yield b
    finally:
        b.close()


def write_viewer(path: Path, password: str) -> Path:
    """The viewer's users file (``ros2:PASSWORD``, mode 0600), in the format ``--credentials`` takes; written
    to a temporary name and renamed, so a script that waits for it never reads it half written."""
    from fleet_emu.core.files import write_atomic

    text = dictionary_text({VIEWER: password})
    write_atomic(path, lambda tmp: tmp.write_text(text), mode=0o600)  # never through a link planted there
    return path


class Bridge:
    """The run's ROS 2 node: its session, publishers and tokens, and the thread folding the bus into them."""

    def __init__(self, access: BusAccess, domain: int) -> None:
        self.domain = domain
        self.nonce = access.nonce
        self.fold = Ros2Fold(access.scenario.to_dict(), access.map_data.grid, access.grid_every, access.clock)
        conf = client_config(access.endpoint, access.login)
        conf.insert_json5("timestamping/enabled", "true")  # the advanced publishers' caches sequence by time
        self.session = zenoh.open(conf)
        self.gid = secrets.token_bytes(rmw.GID_SIZE)
        zid = str(self.session.info.zid())
        live = self.session.liveliness()
        self.tokens = [live.declare_token(rmw.node_token(domain, zid, 0, NODE))]
        self.publishers: dict[str, Any] = {}
        self.seq: dict[str, int] = {}
        self.published = 0
        self.failed = False
        for i, (topic, (typename, latched)) in enumerate(sorted(topics(access.scenario.robots).items()), start=1):
            h = type_hash(typename)
            key = rmw.topic_key(domain, topic, typename, h)
            self.tokens.append(live.declare_token(rmw.publisher_token(
                domain, zid, 0, i, NODE, topic, typename, h, rmw.qos(latched))))
            self.publishers[topic] = zenoh.ext.declare_advanced_publisher(
                self.session, key, cache=zenoh.ext.CacheConfig(1), publisher_detection=True) if latched else \
                self.session.declare_publisher(key, congestion_control=zenoh.CongestionControl.DROP)
            self.seq[topic] = 0
        keys = Keys(access.run_id)
        self.subscribers = [self.session.declare_subscriber(k, zenoh.handlers.RingChannel(RING)) for k in (
            keys.state, keys.links, keys.wildcard("world", "obs", "*"), keys.wildcard("robot", "*", "cmd"),
            keys.wildcard("robot", "*", "belief"))]
        self.lock = threading.Lock()
        self.threads = [threading.Thread(target=self._drain, args=(s,), daemon=True, name="ros2 bridge")
                        for s in self.subscribers]
        for t in self.threads:
            t.start()

    def _drain(self, subscriber: Any) -> None:
        for s in subscriber.handler:  # ends once undeclared and empty
            if not of_run(s, self.nonce):
                continue
            try:
                msg: Message = decode(s.payload.to_bytes())
            except DecodeError:
                continue
            with self.lock:
                self._publish(self.fold.fold(msg))

    def _publish(self, items: list[Out]) -> None:
        """Put each message on its topic; an error turns the bridge off, never the run."""
        if self.failed:
            return
        try:
            for o in items:
                seq = self.seq[o.topic] = self.seq[o.topic] + 1
                stamp = self.fold.clock.ns(o.tick)
                self.publishers[o.topic].put(cdr(o.msg, o.typename), attachment=rmw.attachment(seq, stamp, self.gid))
                self.published += 1
        except Exception:
            log.exception("ros2 bridge disabled after an error")
            self.failed = True

    def close(self) -> None:
        """The last messages (paths, coverage), then every declaration undone and the session closed."""
        for s in self.subscribers:
            with contextlib.suppress(zenoh.ZError):
                s.undeclare()
        for t in self.threads:
            t.join(5.0)
        with self.lock:
            self._publish(self.fold.finish())
        for d in [*self.publishers.values(), *self.tokens]:
            with contextlib.suppress(zenoh.ZError):
                d.undeclare()
        with contextlib.suppress(zenoh.ZError):
            self.session.close()
