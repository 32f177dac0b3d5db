"""Floor 3, control: the MPC and its solvers, shared by the scalar reference and the batched
closed loop (docs/model.md, "The MPC"). docs/architecture.md, "The modules", maps its modules.
"""
