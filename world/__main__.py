from fleet_emu.world.node import main

main()
