"""The studies' defaults, in a module that imports nothing: the command line builds its parser
(``--help``) from them without loading JAX or MuJoCo, and the studies run with them.
"""

# studies.basin: the (x_com, v_com) grid and the posture families realising each cell
DEFAULT_X = "-0.2:0.2:0.02"  # m
DEFAULT_V = "-0.6:0.6:0.06"  # m/s
POSTURES = {
    "rigid": "hip straight: the body leans as one rigid body about the ankle",
    "trunk": "trunk vertical: the lower body leans, the upper body stays upright",
}

# studies.landscape: 7 Q and R scales a decade apart around the base weights (1): Q/R ratios
# from 1e-6 to 1e6 of the base's; no delay, and the human-like 100 ms with the
# delay-compensated controller (a plain MPC keeps no recoverable area at 20 ms or more:
# docs/beyond.md, "Delay"); each setting's table (max acting time at 50 N)
DEFAULT_SCALES = "0.001,0.01,0.1,1,10,100,1000"
DEFAULT_DELAYS = "0,100c"
DEFAULT_TABLE_FORCES = "50"  # N

# studies.sensitivity: the readings of the study and the default sweep's table forces
READINGS = {  # key -> (label, configuration changes); plain sets offset_free = false, so a
    # plain reading stays plain on an offset-free base configuration
    "paper_plain": (
        "paper, plain MPC",
        {"controller": {"convention": "paper", "offset_free": False}},
    ),
    "joint_plain": (
        "joint, plain MPC",
        {"controller": {"convention": "joint", "offset_free": False}},
    ),
    "paper_offset_free": (
        "paper, offset-free MPC",
        {"controller": {"convention": "paper", "offset_free": True}},
    ),
    "joint_offset_free": (
        "joint, offset-free MPC",
        {"controller": {"convention": "joint", "offset_free": True}},
    ),
}
DEFAULT_FORCES = "20,50,80,100,120"  # N

# runs.DEFAULT_SWEEP's grid, as --help shows it (runs/ loads JAX; a test keeps the two equal)
DEFAULT_SWEEP_FORCES = "0:150:10"  # N
DEFAULT_SWEEP_DURATIONS = "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5"  # s
DEFAULT_SWEEP_TABLE_FORCES = "20,50,80,100,120"  # N
