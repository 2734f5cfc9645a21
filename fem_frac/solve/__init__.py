"""Time stepping: supports and loads, integrators, equilibrium iteration, linear solvers."""
