from fleet_emu.launch.cli import main

main()
