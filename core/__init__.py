"""What every process of the fleet shares: grid type and kernels, messages, keys, scenario, session helpers."""
