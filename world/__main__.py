from world.node import main

main()
