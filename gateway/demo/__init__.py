"""The demo and its evaluation helpers: the only product code that imports sim_bus."""
