"""Who may write what on the bus: one table, used twice.

1. Zenoh's own access control (the first line): :func:`acl_config` turns the table into the router's
   ``access_control`` block — default deny; every fleet user may subscribe to and receive the run's keys; each
   may put only on the keys of its own role (and declare only its own liveliness token). The recorder puts
   nothing. Users authenticate with Zenoh's user/password scheme (:func:`make_credentials`, one password per
   process and run).
2. Every receiver (the second line): :func:`allowed_src` says which senders a key may carry, and
   ``NodeShell.decode`` / the launcher's monitor drop and count a message whose ``src`` disagrees with its key.

The keys each node writes (docs/reference/protocol.md, docs/design/security.md):

=========  ===================================================================================
world      ``world/**`` (state, obs, clock), ``ctl/hello``, ``ctl/stop``, ``ctl/ready/world``
netem      ``radio/rx/*``, ``netem/links``, ``ctl/ready/netem``
robot rK   ``robot/rK/**`` (cmd, belief, timing), ``radio/tx/rK``, ``ctl/report/rK``, ``ctl/ready/rK``
base       ``radio/tx/base`` (a base-station planner's orders), ``ctl/report/base``, ``ctl/ready/base``
launcher   ``ctl/stop``, ``ctl/failed/*``, ``ctl/ready/launcher``
recorder   nothing (it subscribes to ``fleet/<run>/**``)
host K     nothing in the run (it reads the run's keys, e.g. the launcher's liveliness token)
=========  ===================================================================================

The hosts' lobby (``fleet-host/<host>/...``, ``launch/host_client.py``, outside every run's keys) has rules of its
own (:func:`lobby_rules`): host K may declare its token ``fleet-host/K/alive``, put on ``fleet-host/K/status``
and subscribe to ``fleet-host/K/spawn``; the launcher may put on ``fleet-host/*/spawn`` and subscribe to the
hosts' tokens and statuses. A spawn request carries the host's robots' credentials: no other user may
subscribe to it nor receive it (default deny, on both the ingress and the egress side), and the recorder,
which subscribes to ``fleet/<run>/**``, never sees it.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import secrets
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.files import TooLarge, open_regular
from fleet_emu.core.keys import BASE, HOST_ID, HOST_ROOT, ROOT, ParsedKey
from fleet_emu.core.limits import MAX_FILE_BYTES

WORLD, NETEM, LAUNCHER, RECORDER = "world", "netem", "launcher", "recorder"
SERVICES = (WORLD, NETEM, LAUNCHER, RECORDER)
HOST = "host"

#: Every message kind the router filters; receivers get all of them on the run's keys.
_ALL_MESSAGES = ["put", "delete", "declare_subscriber", "query", "declare_queryable", "reply",
                 "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"]
_SUBSCRIBE = ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query"]


def role_of(node: str) -> str:
    """The liveliness role of a node id (``r3`` is an ``agent``, ``host0`` a ``host``, ``base`` a ``base``)."""
    return node if node in (*SERVICES, BASE) else HOST if HOST_ID.fullmatch(node) else "agent"


def writes(node: str) -> list[str]:
    """The key suffixes (after ``fleet/<run>/``) that ``node`` may put on."""
    if node == WORLD:
        return ["world/**", "ctl/hello", "ctl/stop", "ctl/ready/world"]
    if node == NETEM:
        return ["radio/rx/*", "netem/links", "ctl/ready/netem"]
    if node == LAUNCHER:
        return ["ctl/stop", "ctl/failed/*", "ctl/ready/launcher"]
    if node == RECORDER or role_of(node) == HOST:
        return []
    if node == BASE:  # a fixed radio endpoint; it sends on radio/tx/base when it plans (mhm)
        return [f"radio/tx/{BASE}", f"ctl/report/{BASE}", f"ctl/ready/{BASE}"]
    return [f"robot/{node}/**", f"radio/tx/{node}", f"ctl/report/{node}", f"ctl/ready/{node}"]


def allowed_src(parsed: ParsedKey) -> frozenset[str] | None:
    """The senders whose messages a key may carry (None: not a message key, e.g. a liveliness token)."""
    match parsed.channel:
        case "obs" | "state" | "clock" | "hello":
            return frozenset({WORLD})
        case "stop":
            return frozenset({WORLD, LAUNCHER})
        case "rx" | "links":
            return frozenset({NETEM})
        case "failed":
            return frozenset({LAUNCHER})
        case "cmd" | "belief" | "timing" | "tx" | "report" | "ready":
            return frozenset({parsed.node}) if parsed.node else frozenset()
    return None


@dataclasses.dataclass(frozen=True)
class Grant:
    """Access for one user beyond the run's own keys (the ROS 2 topics of ``fleet run --ros2``): the message
    kinds it may send (``ingress``) or be sent (``egress``) on ``key_exprs``. A user that is no process of the
    fleet (a read-only viewer) gets only its grants."""

    user: str
    flows: tuple[str, ...]
    messages: tuple[str, ...]
    key_exprs: tuple[str, ...]


def acl_config(run: str, nodes: Iterable[str], grants: Iterable[Grant] = ()) -> dict[str, Any]:
    """The router's ``access_control`` block for ``nodes`` (user names = node ids) of run ``run`` (``"*"``
    for a router that serves many runs), and the ``grants``."""
    prefix = f"{ROOT}/{run}"
    nodes = list(nodes)
    rules: list[dict[str, Any]] = [
        {"id": "receive", "permission": "allow", "flows": ["egress"], "messages": _ALL_MESSAGES,
         "key_exprs": [f"{prefix}/**"]},
        {"id": "subscribe", "permission": "allow", "flows": ["ingress"], "messages": _SUBSCRIBE,
         "key_exprs": [f"{prefix}/**"]},
    ]
    subjects: list[dict[str, Any]] = [{"id": "fleet", "usernames": nodes}]
    policies: list[dict[str, Any]] = [{"rules": ["receive", "subscribe"], "subjects": ["fleet"]}]
    for node in nodes:
        if role_of(node) == HOST:  # its liveliness token and its puts are in the lobby
            policies.append({"rules": [], "subjects": [f"user {node}"]})
            subjects.append({"id": f"user {node}", "usernames": [node]})
            continue
        own = [f"{prefix}/{k}" for k in writes(node)]
        subjects.append({"id": f"user {node}", "usernames": [node]})
        names = [f"token {node}"]
        rules.append({"id": f"token {node}", "permission": "allow", "flows": ["ingress"],
                      "messages": ["liveliness_token"], "key_exprs": [f"{prefix}/alive/{role_of(node)}/{node}"]})
        if own:
            rules.append({"id": f"put {node}", "permission": "allow", "flows": ["ingress"], "messages": ["put"],
                          "key_exprs": own})
            names.append(f"put {node}")
        policies.append({"rules": names, "subjects": [f"user {node}"]})
    lobby = lobby_rules(nodes)
    rules += [r for rs in lobby.values() for r in rs]
    for node, rs in lobby.items():
        policy = next(p for p in policies if p["subjects"] == [f"user {node}"])
        policy["rules"] += [r["id"] for r in rs]
    _grant(grants, rules, subjects, policies)
    policies = [p for p in policies if p["rules"]]
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def _grant(grants: Iterable[Grant], rules: list[dict[str, Any]], subjects: list[dict[str, Any]],
           policies: list[dict[str, Any]]) -> None:
    """Add each grant's rule to its user's policy (a new subject and policy for a user not yet named)."""
    for i, g in enumerate(grants):
        rule = f"grant {i} {g.user}"
        rules.append({"id": rule, "permission": "allow", "flows": list(g.flows), "messages": list(g.messages),
                      "key_exprs": list(g.key_exprs)})
        policy = next((p for p in policies if p["subjects"] == [f"user {g.user}"]), None)
        if policy is None:
            subjects.append({"id": f"user {g.user}", "usernames": [g.user]})
            policy = {"rules": [], "subjects": [f"user {g.user}"]}
            policies.append(policy)
        policy["rules"].append(rule)


def lobby_rules(nodes: Iterable[str]) -> dict[str, list[dict[str, Any]]]:
    """The hosts' lobby rules (``fleet-host/...``), per user: each host's own keys, and the launcher's."""
    out: dict[str, list[dict[str, Any]]] = {}
    hosts = [n for n in nodes if role_of(n) == HOST]
    for h in hosts:
        base = f"{HOST_ROOT}/{h}"
        out[h] = [
            {"id": f"lobby put {h}", "permission": "allow", "flows": ["ingress"], "messages": ["put"],
             "key_exprs": [f"{base}/status"]},
            {"id": f"lobby token {h}", "permission": "allow", "flows": ["ingress"], "messages": ["liveliness_token"],
             "key_exprs": [f"{base}/alive"]},
            {"id": f"lobby subscribe {h}", "permission": "allow", "flows": ["ingress"],
             "messages": ["declare_subscriber"], "key_exprs": [f"{base}/spawn"]},
            {"id": f"lobby receive {h}", "permission": "allow", "flows": ["egress"], "messages": ["put"],
             "key_exprs": [f"{base}/spawn"]},
            # a publisher sends only where it has heard of a subscriber: the launcher's must reach the host
            {"id": f"lobby matching {h}", "permission": "allow", "flows": ["egress"],
             "messages": ["declare_subscriber"], "key_exprs": [f"{base}/status"]},
        ]
    if LAUNCHER in nodes:
        watch = [f"{HOST_ROOT}/*/alive", f"{HOST_ROOT}/*/status"]
        out[LAUNCHER] = [
            {"id": "lobby put launcher", "permission": "allow", "flows": ["ingress"], "messages": ["put"],
             "key_exprs": [f"{HOST_ROOT}/*/spawn"]},
            {"id": "lobby watch launcher", "permission": "allow", "flows": ["ingress"], "messages": _SUBSCRIBE,
             "key_exprs": watch},
            {"id": "lobby receive launcher", "permission": "allow", "flows": ["egress"],
             "messages": ["put", "liveliness_token"], "key_exprs": watch},
            {"id": "lobby matching launcher", "permission": "allow", "flows": ["egress"],
             "messages": ["declare_subscriber"], "key_exprs": [f"{HOST_ROOT}/*/spawn"]},
        ]
    return out


@dataclasses.dataclass(frozen=True)
class Credential:
    """One process's login on the bus (and, for a TLS router, the CA certificate that signs it)."""

    user: str
    password: str
    tls_ca: str | None = None

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self))

    @classmethod
    def from_json(cls, text: str) -> Credential:
        obj = json.loads(text)
        if not isinstance(obj, dict) or not isinstance(obj.get("user"), str) \
                or not isinstance(obj.get("password"), str):
            raise ValueError("expected a JSON object with 'user' and 'password'")
        ca = obj.get("tls_ca")
        return cls(obj["user"], obj["password"], ca if isinstance(ca, str) else None)


def fleet_nodes(robots: Iterable[str], base: bool = False) -> list[str]:
    """Every user of a run: the services, the base station when the run has one, and the robots."""
    return [*SERVICES, *([BASE] if base else []), *robots]


def make_credentials(nodes: Iterable[str]) -> dict[str, str]:
    """A fresh random password per node (``secrets``: these are keys, not simulation draws)."""
    return {n: secrets.token_urlsafe(24) for n in nodes}


def dictionary_text(passwords: dict[str, str]) -> str:
    """Zenoh's ``usrpwd`` dictionary file: ``user:password`` lines."""
    return "".join(f"{u}:{p}\n" for u, p in passwords.items())


def read_dictionary(text: str) -> dict[str, str]:
    """The inverse of :func:`dictionary_text`; ValueError on a malformed line."""
    out: dict[str, str] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        user, sep, password = line.partition(":")
        if not sep or not user or not password:
            raise ValueError(f"line {n} is not user:password")
        out[user] = password
    return out


def read_users(path: Path, option: str = "--credentials") -> dict[str, str]:
    """A users file (:func:`dictionary_text`'s ``user:password`` lines) read as ssh reads a private key: a
    ConfigError naming ``chmod 600`` when its group or others may read or write it (its passwords are then no
    one's own), or when it cannot be read; ``option`` names it for the user."""
    try:
        with open_regular(path) as f:  # a FIFO or a device refused at once, never waited on
            mode = os.fstat(f.fileno()).st_mode
            data = b"" if mode & 0o077 else f.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:
            raise TooLarge(errno.EFBIG, f"larger than {MAX_FILE_BYTES >> 20} MiB")
    except OSError as exc:
        raise ConfigError(f"{option} {path}: cannot read it ({exc.strerror or exc})") from None
    if mode & 0o077:
        raise ConfigError(f"{option} {path} is open to its group or others (mode {stat.S_IMODE(mode):04o}): its "
                          f"passwords must be yours alone; chmod 600 {path}")
    try:
        return read_dictionary(data.decode())
    except (UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"{option} {path}: cannot read it ({exc})") from None
