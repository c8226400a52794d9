"""``python -m fleet_emu ARGS``: the ``fleet`` command."""

from fleet_emu.cli import main

main()
