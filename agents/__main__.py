from fleet_emu.agents.node import main

main()
