"""``fleet router-config``: a zenohd configuration with the fleet's authentication and access control.

For ``fleet run --connect`` to a router of your own (one that robots on other machines also reach). The users
file holds one ``user:password`` line per process of a fleet of up to ``--robots`` robots; zenohd reads it as
its ``usrpwd`` dictionary, and ``fleet run --credentials`` gives each process its own line; with ``--hosts N``
it also holds ``host0`` .. ``host<N-1>``, the logins of ``fleet host`` (give each host only its own line).
The access control is the embedded router's (``core/access.py``): default deny, each user may put only on its own keys.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from fleet_emu.core.access import acl_config, dictionary_text, fleet_nodes, make_credentials, read_users
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.keys import RUN_ID, host_ids, robot_ids
from fleet_emu.core.scenario import MAX_ROBOTS


def write_users(path: Path, nodes: list[str]) -> dict[str, str]:
    """The users file at ``path``: kept passwords are reused, missing users get new ones; written with mode
    0600 through a temporary file and a rename."""
    users: dict[str, str] = {}
    if path.exists():
        users = read_users(path, "--users")
    users |= make_credentials(n for n in nodes if n not in users)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(dictionary_text(users))
        os.replace(tmp, path)
    except OSError as exc:
        raise ConfigError(f"--users {path}: cannot write it ({exc.strerror or exc})") from None
    return users


def router_config_text(robots: int, users: Path, listen: str | None = None, run_id: str = "*",
                       tls_cert: Path | None = None, tls_key: Path | None = None, hosts: int = 0) -> str:
    """The JSON5 (plain JSON) configuration to start zenohd with (``zenohd -c FILE``)."""
    if not 1 <= robots <= MAX_ROBOTS:
        raise ConfigError(f"--robots must be in 1..{MAX_ROBOTS} (got {robots})")
    if run_id != "*" and not RUN_ID.fullmatch(run_id):
        raise ConfigError(f"--run-id must be letters, digits, '_', '-' or '.' (not first), or '*' (got {run_id!r})")
    if (tls_cert is None) != (tls_key is None):
        raise ConfigError("--tls-cert and --tls-key go together")
    for flag, f in (("--tls-cert", tls_cert), ("--tls-key", tls_key)):
        if f is not None and not f.is_file():
            raise ConfigError(f"{flag} {f}: no such file")
    listen = listen or ("tls/0.0.0.0:7447" if tls_cert else "tcp/0.0.0.0:7447")
    if tls_cert is not None and not listen.startswith("tls/"):
        raise ConfigError(f"--listen {listen}: with a TLS certificate the endpoint must be tls/...")
    if not 0 <= hosts <= 64:
        raise ConfigError(f"--hosts must be in 0..64 (got {hosts})")
    nodes = fleet_nodes(robot_ids(robots), base=True) + host_ids(hosts)  # a base user for runs with one
    write_users(users, nodes)
    transport: dict = {"auth": {"usrpwd": {"dictionary_file": str(users.absolute())}}}
    if tls_cert is not None and tls_key is not None:
        transport["link"] = {"tls": {"listen_certificate": str(tls_cert.absolute()),
                                     "listen_private_key": str(tls_key.absolute())}}
    conf = {
        "mode": "router",
        "listen": {"endpoints": [listen]},
        "scouting": {"multicast": {"enabled": False}},
        "transport": transport,
        "access_control": acl_config(run_id, nodes),
    }
    return json.dumps(conf, indent=2)
