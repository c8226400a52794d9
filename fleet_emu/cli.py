"""``fleet``, the console script: every command, composed at the top of the package.

``run``, ``router-config``, ``host``, ``maps``, ``allocators`` and ``report`` come from
:mod:`fleet_emu.launch.cli`, ``sweep`` from :mod:`fleet_emu.sweep.cli`; sweep runs its fleets through launch, so
only a module above both can offer them side by side (launch never imports sweep). Nothing heavy is imported
before the dispatcher has installed its signal handlers: a signal during start-up is a request, not a traceback.
"""

from __future__ import annotations

import argparse

from fleet_emu.launch import cli as launch_cli


def build_parser() -> argparse.ArgumentParser:
    """The whole ``fleet`` parser."""
    from fleet_emu.sweep.cli import add_parser as add_sweep

    return launch_cli.build_parser(extra=(add_sweep,))


def _sweep(args: argparse.Namespace) -> int:
    from fleet_emu.sweep.cli import cmd_sweep

    return cmd_sweep(args)


def main(argv: list[str] | None = None) -> None:
    """``fleet ARGS`` (``python -m fleet_emu ARGS``): parse, run the command, exit with its code."""
    launch_cli.serve(argv, build_parser, {**launch_cli.HANDLERS, "sweep": _sweep})


if __name__ == "__main__":
    main()
