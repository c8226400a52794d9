from fleet_emu.netem.node import main

main()
