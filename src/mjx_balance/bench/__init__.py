"""Floor 11, bench: benchmarks as library functions that compute and return figures (the
solvers, the whole closed loop, the physics, the engine); ``cli.bench`` prints them.
docs/architecture.md, "The modules", maps its modules; BENCHMARKS.md holds the measurements.

The submodules are imported by name; this package imports none of them.
"""
