from netem.node import main

main()
