"""Benchmarks as library functions that compute and return figures; ``cli.bench`` prints them.

    states.py    the solver benchmark's closed-loop states, the OSQP truth at eps 1e-9, the
                 ADMM along the trajectories and the warm-started OSQP loop
    ipopt.py     the study's MPC: CasADi/IPOPT (multiple shooting, RK4 on Ac, Bc), and
                 IpoptMPC, the reference closed loop's controller interface around it
    solver.py    ``mjx-balance bench solver``: batched ADMM vs OSQP vs CasADi/IPOPT on the same
                 states (accuracy, solves per second, FLOP/s against the CPU's peak)
    pipeline.py  ``mjx-balance bench``: the whole closed loop, MJX + ADMM vs the scalar
                 reference vs the study's toolchain (scenarios per second, outcome agreement,
                 peak memory, memory scaling of sweeps)

The submodules are imported by name; this package imports none of them.
"""
