"""Attacks on the bus against a seeded fleet, one at a time, and what each did to the result.

    python3 benchmarks/attacks.py                      # both modes, office, 3 robots, seed 3
    python3 benchmarks/attacks.py --mode open          # only an unauthenticated router (what every run had before)

Each attack runs as an outside Zenoh session beside a ``fleet run --connect`` to a router this script opens:

- ``open``: a router without authentication or access control; the attacker needs no credentials. Only the
  receivers' own checks stand in the way.
- ``auth``: the router of ``fleet router-config`` (user/password authentication, default-deny access control);
  the attacker holds robot r2's credentials and impersonates the others.

A row says whether the run's deterministic result differs from the unattacked run of the same seed. In ``open``
mode this script only needs ``fleet run --connect``, so it runs against older versions of the project too.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import msgpack
import numpy as np
import zenoh

Put = Callable[[str, bytes], None]
VOLATILE = {"run_id", "pids", "recording", "decision_ms", "wall_seconds", "ticks_per_second", "robot_peak_rss_kb",
            "agent_peak_rss_kb", "malformed_dropped", "malformed_dropped_by", "authenticated", "signal", "bus"}


def _msg(kind: str, src: str, tick: int, **fields: object) -> bytes:
    return msgpack.packb({"kind": kind, "v": 2, "src": src, "tick": tick, "seq": 1, **fields}, use_bin_type=True)


def _arr(a: np.ndarray) -> dict:
    return {"dtype": a.dtype.name, "shape": list(a.shape), "data": a.tobytes()}


def stop_from_outsider(put: Put, t: int, shape: tuple[int, int]) -> None:
    put("ctl/stop", _msg("stop", "outsider", t, reason="pwned"))


def fail_a_robot(put: Put, t: int, shape: tuple[int, int]) -> None:
    put("ctl/failed/r1", _msg("failed", "launcher", t, robot="r1", reason="spoofed"))


def walls_from_r1(put: Put, t: int, shape: tuple[int, int]) -> None:
    cells = np.arange(shape[0] * shape[1], dtype=np.int64)
    payload = msgpack.packb({"cells": _arr(cells), "values": _arr(np.full(cells.size, 100, np.int8))},
                            use_bin_type=True)
    env = {"kind": "radio", "v": 2, "src": "r1", "tick": t, "seq": 9999, "origin": "r1", "dst": "*", "ttl": 0,
           "payload_kind": "map", "payload": payload}
    put("radio/tx/r1", _msg("tx", "r1", t, msgs=[env]))


def stay_commands(put: Put, t: int, shape: tuple[int, int]) -> None:
    for r in ("r0", "r1"):
        put(f"robot/{r}/cmd", _msg("cmd", r, t, move=[0, 0]))
        put(f"robot/{r}/cmd", _msg("cmd", r, t + 1, move=[0, 0]))


def forged_state(put: Put, t: int, shape: tuple[int, int]) -> None:
    put("world/state", _msg("state", "world", t + 5000, poses={}, live=[], coverage=1.0, path_length={},
                            done=True, reason="coverage"))


def fake_rx(put: Put, t: int, shape: tuple[int, int]) -> None:
    for r in ("r0", "r1"):
        put(f"radio/rx/{r}", _msg("rx", "netem", t + 1, dst=r, msgs=[]))


ATTACKS: dict[str, Callable[[Put, int, tuple[int, int]], None]] = {
    "ctl/stop from an outsider": stop_from_outsider,
    "ctl/failed/r1 (a healthy robot)": fail_a_robot,
    "map delta 'from r1': every cell a wall": walls_from_r1,
    "'stay' commands for r0, r1": stay_commands,
    "world/state at tick+5000, coverage 1.0": forged_state,
    "empty rx bundles 'from netem'": fake_rx,
}


def _router(mode: str, work: Path) -> tuple[zenoh.Session, Path | None]:
    if mode == "open":
        conf = zenoh.Config()
        for k, v in (("mode", '"router"'), ("listen/endpoints", '["tcp/127.0.0.1:0"]'),
                     ("scouting/multicast/enabled", "false"), ("adminspace/enabled", "true")):
            conf.insert_json5(k, v)
        return zenoh.open(conf), None
    from fleet_emu.launch.router_config import router_config_text

    users = work / "users.txt"
    conf = zenoh.Config.from_json5(router_config_text(3, users, listen="tcp/127.0.0.1:0"))
    conf.insert_json5("adminspace/enabled", "true")
    return zenoh.open(conf), users


def _endpoint(router: zenoh.Session) -> str:
    zid = str(router.info.zid())
    return next(json.loads(r.ok.payload.to_bytes())["locators"][0] for r in router.get(f"@/{zid}/router") if r.ok)


def _attacker(endpoint: str, users: Path | None) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if users is not None:  # a robot of the fleet (r2) that impersonates the others
        pw = dict(line.split(":", 1) for line in users.read_text().splitlines())["r2"]
        conf.insert_json5("transport/auth/usrpwd/user", '"r2"')
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(pw))
    return zenoh.open(conf)


def run_one(args: argparse.Namespace, endpoint: str, users: Path | None, run_id: str, out: Path,
            attack: Callable[[Put, int, tuple[int, int]], None] | None) -> tuple[dict, int, int]:
    cmd = [sys.executable, "-m", "fleet_emu.launch", "run", "--map", args.map, "--robots", "3", "--seed",
           str(args.seed), "--max-ticks", str(args.max_ticks), "--quiet", "--connect", endpoint, "--run-id", run_id,
           "--out", str(out)]
    if users is not None:
        cmd += ["--credentials", str(users)]
    done = threading.Event()
    sent = [0]

    def flood() -> None:
        tick, shape, started = [0], [(1, 1)], threading.Event()

        def on(kind: str, s: zenoh.Sample) -> None:
            obj = msgpack.unpackb(s.payload.to_bytes())
            if kind == "obs":
                shape[0] = tuple(obj["shape"])
            tick[0] = max(tick[0], obj["tick"])
            started.set()

        with _attacker(endpoint, users) as s:
            subs = [s.declare_subscriber(f"fleet/{run_id}/world/state", lambda x: on("state", x)),
                    s.declare_subscriber(f"fleet/{run_id}/world/obs/r0", lambda x: on("obs", x))]
            started.wait(300)
            while not done.is_set():
                attack(lambda k, d: s.put(f"fleet/{run_id}/{k}", d), tick[0], shape[0])  # type: ignore[misc]
                sent[0] += 1
                time.sleep(0.01)
            for sub in subs:
                sub.undeclare()

    th = threading.Thread(target=flood, daemon=True) if attack else None
    if th:
        th.start()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    done.set()
    if th:
        th.join(10)
    res = json.loads((out / "result.json").read_text()) if (out / "result.json").exists() else {}
    return res, proc.returncode, sent[0]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mode", choices=("open", "auth", "both"), default="both")
    p.add_argument("--map", default="office")
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--max-ticks", type=int, default=400)
    args = p.parse_args(argv)
    modes = ("open", "auth") if args.mode == "both" else (args.mode,)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for mode in modes:
            work = Path(tmp) / mode
            work.mkdir()
            router, users = _router(mode, work)
            with router:
                endpoint = _endpoint(router)
                base, code, _ = run_one(args, endpoint, users, f"{mode}-base", work / "base", None)
                print(f"[{mode}] baseline: exit {code}, {base.get('ticks')} ticks, coverage {base.get('coverage')}",
                      file=sys.stderr)
                for i, (name, attack) in enumerate(ATTACKS.items()):
                    res, code, sent = run_one(args, endpoint, users, f"{mode}-a{i}", work / f"a{i}", attack)
                    same = {k: v for k, v in res.items() if k not in VOLATILE} == \
                        {k: v for k, v in base.items() if k not in VOLATILE}
                    rows.append((mode, name, sent, code, res.get("ticks"), res.get("coverage"), res.get("reason"),
                                 res.get("failed"), res.get("malformed_dropped"), "same" if same else "CHANGED"))
                    print(f"[{mode}] {name}: {rows[-1][3:]}", file=sys.stderr)
    print(f"baseline per mode: seed {args.seed}, map {args.map}, 3 robots, max ticks {args.max_ticks}")
    print("| mode | attack | rounds sent | exit | ticks | coverage | reason | failed | malformed_dropped | result |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(str(c) for c in row) + " |")
    sys.exit(0 if all(r[-1] == "same" for r in rows if r[0] == "auth") else 1)


if __name__ == "__main__":
    main()
