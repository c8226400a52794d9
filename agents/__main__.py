from agents.node import main

main()
