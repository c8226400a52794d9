"""``python -m fleet_emu.launch ARGS``: ``fleet``'s commands but ``sweep`` (``python -m fleet_emu`` has them all)."""

from fleet_emu.launch.cli import main

main()
