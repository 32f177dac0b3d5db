"""Floor 3, control: the MPC and its solvers.

    qp.py           the condensed QP of the MPC over a fixed horizon
    admm.py         the batched ADMM QP solver (pure JAX)
    osqp_mpc.py     the reference MPC solved by OSQP
    offset_free.py  the input-disturbance observer and steady-state target (offset-free MPC)
    certificate.py  the recovery certificate: when a settled scenario provably stays settled
"""
