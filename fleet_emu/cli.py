"""``fleet``, the console script: every command, composed at the top of the package.

``run``, ``router-config``, ``host``, ``maps``, ``allocators`` and ``report`` come from
:mod:`fleet_emu.launch.cli`, ``sweep`` from :mod:`fleet_emu.sweep.cli`, ``export`` and ``run --ros2`` from
:mod:`fleet_emu.ros2.cli`; sweep and ros2 sit above launch, so only a module above them all can offer them side by
side (launch imports neither). Nothing heavy is imported before the dispatcher has installed its signal handlers:
a signal during start-up is a request, not a traceback.
"""

from __future__ import annotations

import argparse

from fleet_emu.launch import cli as launch_cli


def build_parser() -> argparse.ArgumentParser:
    """The whole ``fleet`` parser."""
    from fleet_emu.ros2.cli import add_export, add_run_flags
    from fleet_emu.sweep.cli import add_parser as add_sweep

    parser = launch_cli.build_parser(extra=(add_sweep, add_export))
    add_run_flags(parser)
    return parser


def _sweep(args: argparse.Namespace) -> int:
    from fleet_emu.sweep.cli import cmd_sweep

    return cmd_sweep(args)


def _export(args: argparse.Namespace) -> int:
    from fleet_emu.ros2.cli import cmd_export

    return cmd_export(args)


def main(argv: list[str] | None = None) -> None:
    """``fleet ARGS`` (``python -m fleet_emu ARGS``): parse, run the command, exit with its code."""
    launch_cli.serve(argv, build_parser, {**launch_cli.HANDLERS, "sweep": _sweep, "export": _export})


if __name__ == "__main__":
    main()
