"""The ``fleet`` command line's ROS 2 parts: ``fleet run --ros2 [DOMAIN] [--ros2-listen ENDPOINT]`` and
``fleet export ros2 RUN_DIR [--out BAG]``. :mod:`fleet_emu.cli` adds them (this package sits above launch,
which cannot import it); ``fleet run`` asks ``args.companions`` for the bus's companions and their options."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class Companions:
    """What ``--ros2`` adds to a run: the flag (for errors) and the ``RunOptions`` fields it sets."""

    flag: str
    options: dict[str, Any]


def _domain(text: str) -> int:
    try:
        domain = int(text)
    except ValueError:
        domain = -1
    if not 0 <= domain <= 232:  # ROS 2's domain ids
        raise argparse.ArgumentTypeError(f"expected a ROS domain id from 0 to 232, got {text!r}")
    return domain


def add_run_flags(parser: argparse.ArgumentParser) -> None:
    """``--ros2`` and ``--ros2-listen`` on the ``run`` subcommand's parser."""
    for action in parser._subparsers._group_actions if parser._subparsers else ():
        run = getattr(action, "choices", {}).get("run")
        if run is None:
            continue
        g = run.add_argument_group("ROS 2 (the ros2 extra; docs/guides/ros2.md)")
        g.add_argument("--ros2", type=_domain, nargs="?", const=0, default=None, metavar="DOMAIN",
                       help="publish the run as ROS 2 topics in rmw_zenoh's format on its router (domain 0 "
                            "unless given); prints `ros2: ENDPOINT domain N [credentials FILE]` on stderr")
        g.add_argument("--ros2-listen", metavar="ENDPOINT",
                       help="with --ros2: the embedded router's endpoint for ROS 2 users (e.g. tcp/127.0.0.1:7447, "
                            "rmw_zenoh's default)")
        run.set_defaults(companions=companions)


def companions(args: argparse.Namespace) -> Companions | None:
    """``--ros2``'s companion and grants, checked (None without ``--ros2``); ``--ros2-listen`` becomes the
    embedded router's ``--listen``."""
    if args.ros2 is None:
        if args.ros2_listen is not None:
            raise ConfigError("--ros2-listen goes with --ros2")
        return None
    from fleet_emu.ros2.bridge import Ros2Options
    from fleet_emu.ros2.types import typestore

    typestore()  # the ros2 extra is installed, or one line saying so
    if args.ros2_listen is not None:
        if args.connect is not None:
            raise ConfigError("--ros2-listen sets the embedded router's endpoint: with --connect, ROS 2 users "
                              "connect to that router")
        if args.listen is not None and args.listen != args.ros2_listen:
            raise ConfigError("--listen and --ros2-listen name two endpoints: the router has one, give one")
        args.listen = args.ros2_listen
    opts = Ros2Options.new(args.ros2, authenticated=args.connect is None)
    return Companions("--ros2", opts.run_options())


def add_export(sub: Any) -> None:
    """``fleet export ros2 RUN_DIR [--out BAG] [--partial]``."""
    ex = sub.add_parser("export", help="convert a recording to another format (ros2: a rosbag2)")
    kinds = ex.add_subparsers(dest="format", metavar="FORMAT", parser_class=type(ex))
    kinds.required = True
    r = kinds.add_parser("ros2", help="a rosbag2 (MCAP storage, CDR) of the run's ROS 2 topics")
    r.add_argument("run", type=Path, metavar="RUN", help="a run directory or its run.mcap")
    r.add_argument("--out", type=Path, metavar="BAG", help="the bag's directory (default RUN_DIR/ros2; must not exist)")
    r.add_argument("--partial", action="store_true",
                   help="export what a cut or inconsistent recording holds (without it: refused, saying how much "
                        "reads)")


def cmd_export(args: argparse.Namespace) -> int:
    from fleet_emu.ros2.export import export
    from fleet_emu.ros2.types import typestore

    typestore()
    out, counts = export(args.run, args.out, partial=args.partial)
    print(f"{out}: {sum(counts.values())} messages on {len(counts)} topics")
    return 0
