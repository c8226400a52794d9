"""``fleet router-config``: a zenohd configuration with the fleet's authentication and access control.

For ``fleet run --connect`` to a router of your own (one that robots on other machines also reach). The users
file holds one ``user:password`` line per process of a fleet of up to ``--robots`` robots; zenohd reads it as
its ``usrpwd`` dictionary, and ``fleet run --credentials`` gives each process its own line; with ``--hosts N``
it also holds ``host0`` .. ``host<N-1>``, the logins of ``fleet host`` (give each host only its own line).
The access control is the embedded router's (``core/access.py``): default deny, each user may put only on its own keys.

With several run ids (``--run-id a --run-id b``) the router serves each of them, and each with logins of its
own: ``a.world``, ``a.r0``, ... act only on ``fleet/a/``. The router's users file then holds them all, and
``FILE-a`` (beside it: ``users-a.txt`` for ``users.txt``) only run ``a``'s, the one file to give whoever runs
fleets as run ``a`` (``fleet run --connect ... --credentials users-a.txt --run-id a``): a launcher's file no
longer holds logins that act on another's runs (docs/design/security.md).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fleet_emu.core.access import acl_config, dictionary_text, fleet_nodes, make_credentials, read_users
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.files import write_atomic
from fleet_emu.core.keys import RUN_ID, host_ids, robot_ids
from fleet_emu.core.scenario import MAX_ROBOTS


def write_users(path: Path, nodes: list[str]) -> dict[str, str]:
    """The users file at ``path``: kept passwords are reused, missing users get new ones; written with mode
    0600 through a temporary file and a rename."""
    users: dict[str, str] = {}
    if path.exists():
        users = read_users(path, "--users")
    users |= make_credentials(n for n in nodes if n not in users)
    _write_dictionary(path, users)
    return users


def run_users_file(users: Path, run: str) -> Path:
    """The users file of one run id beside the router's (``users-a.txt`` for ``users.txt`` and run ``a``)."""
    return users.with_name(f"{users.stem}-{run}{users.suffix}")


def _write_dictionary(path: Path, users: dict[str, str]) -> None:
    text = dictionary_text(users)
    try:
        write_atomic(path, lambda tmp: tmp.write_text(text), mode=0o600)  # never through a link planted there
    except OSError as exc:
        raise ConfigError(f"--users {path}: cannot write it ({exc.strerror or exc})") from None


def router_config_text(robots: int, users: Path, listen: str | None = None, run_id: str | list[str] = "*",
                       tls_cert: Path | None = None, tls_key: Path | None = None, hosts: int = 0) -> str:
    """The JSON5 (plain JSON) configuration to start zenohd with (``zenohd -c FILE``); ``run_id``: one run id
    (``"*"``: any run), or several, each with logins of its own (the module's docstring)."""
    if not 1 <= robots <= MAX_ROBOTS:
        raise ConfigError(f"--robots must be in 1..{MAX_ROBOTS} (got {robots})")
    runs = [run_id] if isinstance(run_id, str) else list(dict.fromkeys(run_id)) or ["*"]
    for run in runs:
        if not (run == "*" and len(runs) == 1) and not RUN_ID.fullmatch(run):
            raise ConfigError(f"--run-id must be letters, digits, '_', '-' or '.' (not first), or '*' alone "
                              f"(got {run!r})")
    if len(runs) > 1 and hosts:
        raise ConfigError("--hosts goes with one --run-id (the hosts' logins serve one run id, or any)")
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
    if len(runs) > 1:
        logins = write_users(users, [f"{run}.{n}" for run in runs for n in nodes])
        for run in runs:
            _write_dictionary(run_users_file(users, run), {u: p for u, p in logins.items()
                                                            if u.rpartition(".")[0] == run})
    else:
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
        "access_control": acl_config(runs[0], nodes) if len(runs) == 1 else per_run_acl(runs, nodes),
    }
    return json.dumps(conf, indent=2)


def per_run_acl(runs: list[str], nodes: list[str]) -> dict[str, Any]:
    """The access control of several runs, each with logins of its own (``RUN.node``): each run's block of
    :func:`~fleet_emu.core.access.acl_config`, its users and ids tagged with the run."""
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for run in runs:
        acl, tag = acl_config(run, nodes), f"{run}."
        rules += [r | {"id": tag + r["id"]} for r in acl["rules"]]
        subjects += [{"id": tag + s["id"], "usernames": [tag + u for u in s["usernames"]]} for s in acl["subjects"]]
        policies += [{"rules": [tag + r for r in p["rules"]], "subjects": [tag + s for s in p["subjects"]]}
                     for p in acl["policies"]]
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}
