"""Watch a ``fleet run --ros2`` with a ROS 2 client nobody here wrote: ``zenoh-ros2-sdk`` (rmw_zenoh's format from
Python, no ROS installation). Prints each robot's map size as its maps come and its pose every tick.

    python3 docs/ros2/listen.py ENDPOINT ROBOTS [--credentials FILE] [--domain N] [--seconds S]

ENDPOINT and FILE are what the run prints (``ros2: ENDPOINT domain N credentials FILE``). The SDK would fetch
message definitions with git at run time; they are written here from rosbags' type store instead (offline), and
the SDK computes the type hashes from them itself, so a subscription that receives anything also agrees with the
fleet's hashes. One line per message (the SDK calls back from several threads: a line is written whole, under a
lock); a wrong credentials file, an endpoint that is not one, or no router there is one line and exit 2.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, NoReturn

MAP, POSE = "nav_msgs/msg/OccupancyGrid", "geometry_msgs/msg/PoseStamped"


def write_msg_files(root: Path, typenames: list[str]) -> None:
    """One ``.msg`` file per type and its dependencies (``<pkg>/msg/<Name>.msg``), from rosbags' Jazzy store."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    todo, seen = list(typenames), set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        text = store.generate_msgdef(name, ros_version=2)[0].split("\n" + "=" * 80 + "\n")
        path = root / f"{name}.msg"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text[0])
        todo += ["/msg/".join(part.removeprefix("MSG: ").split("/", 1)) for part in
                 (t.splitlines()[0] for t in text[1:])]


_OUT = threading.Lock()


def say(line: str) -> None:
    """One whole line on standard output: callbacks of several threads never run two lines together."""
    with _OUT:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


def fail(message: str) -> NoReturn:
    print(f"listen.py: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def show_map(robot: str, m: Any) -> None:
    say(f"{robot} map {m.info.width}x{m.info.height} known {int((m.data >= 0).sum())}")


def show_pose(robot: str, m: Any) -> None:
    stamp = f"{m.header.stamp.sec}.{m.header.stamp.nanosec:09d}"
    say(f"{robot} pose {stamp} {m.pose.position.x:.2f} {m.pose.position.y:.2f}")


def login(path: Path) -> tuple[str, str]:
    """The first ``user:password`` line of ``path``; one line and exit 2 when it cannot be read or is not one."""
    try:
        first = path.read_text().split("\n")[0]
    except (OSError, UnicodeDecodeError) as exc:
        fail(f"--credentials {path}: {getattr(exc, 'strerror', None) or exc} (the ros2.users file the run printed)")
    user, colon, password = first.partition(":")
    if not (user and colon and password):
        fail(f"--credentials {path}: its first line is not user:password")
    return user, password


def router(endpoint: str) -> tuple[str, int]:
    """``tcp/HOST:PORT`` as the SDK takes it; one line and exit 2 for anything else."""
    host, colon, port = endpoint.removeprefix("tcp/").rpartition(":")
    if not (endpoint.startswith("tcp/") and colon and host and port.isdigit()):
        fail(f"{endpoint!r} is not a tcp/HOST:PORT endpoint (the run prints its own: ros2: ENDPOINT ...)")
    return host, int(port)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("endpoint", help="tcp/HOST:PORT, as the run printed it")
    p.add_argument("robots", type=int)
    p.add_argument("--credentials", type=Path, help="the run's ros2.users file (user:password)")
    p.add_argument("--domain", type=int, default=0)
    p.add_argument("--seconds", type=float, default=30.0, help="how long to listen")
    args = p.parse_args()
    host, port = router(args.endpoint)
    override = ['mode="client"', 'scouting/multicast/enabled=false']
    if args.credentials is not None:
        user, password = login(args.credentials)
        override += [f"transport/auth/usrpwd/user={json.dumps(user)}",
                     f"transport/auth/usrpwd/password={json.dumps(password)}"]
    os.environ["ZENOH_CONFIG_OVERRIDE"] = ";".join(override)
    with tempfile.TemporaryDirectory() as messages:
        write_msg_files(Path(messages), [MAP, POSE])
        from zenoh_ros2_sdk import ROS2Subscriber, get_registry

        get_registry(messages)  # the SDK's registry reads the definitions from here, not from git
        where = {"domain_id": args.domain, "router_ip": host, "router_port": port}
        subs = []
        try:
            for i in range(args.robots):
                r = f"r{i}"
                subs.append(ROS2Subscriber(f"/{r}/map", MAP, lambda m, r=r: show_map(r, m), **where))
                subs.append(ROS2Subscriber(f"/{r}/pose", POSE, lambda m, r=r: show_pose(r, m), **where))
        except Exception as exc:  # the SDK's session: zenoh.ZError when no router answers or it refuses the login
            fail(f"no Zenoh router at {args.endpoint} let us in ({str(exc).split('!')[0].strip()}): is the run "
                 f"still going, and are the credentials its ros2.users?")
        say("subscribed")
        time.sleep(args.seconds)
        for s in subs:
            s.close()


if __name__ == "__main__":
    main()
