"""Fit the shipped MLP policy (src/mjx_balance/data/policies/mlp_mpc.npz) to imitate the
study's MPC: the MPC's first input (OSQP on the condensed QP, cold, converged solves only) at
states sampled from the MPC's own closed-loop runs (the scalar reference, pushes of 20-120 N
for 0.1-0.5 s, 3-s windows) and uniformly around upright, then a 4-64-64-2 tanh network fitted
by full-batch Adam on the squared error relative to each input's range. Prints the fit's error
on held-out states. Nothing in the package trains; this script makes the file it loads.

    python docs/scripts/fit_policy.py [--out PATH] [--steps 6000] [--seed 0]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from mjx_balance.control import policy
from mjx_balance.model.params import Config
from mjx_balance.reference import loop as reference

WIDTH = 64
FORCES, DURATIONS = (20.0, 40.0, 60.0, 80.0, 100.0, 120.0), (0.1, 0.2, 0.3, 0.5)


def visited_states(config: Config, every: int = 5) -> np.ndarray:
    """Convention states of the MPC's own runs (every ``every``-th physics step)."""
    states = []
    for force in FORCES:
        for duration in DURATIONS:
            _, series = reference.simulate_scenario(config, force, duration, record=True)
            states.append(series[["x1", "x2", "x3", "x4"]].to_numpy()[::every])
    return np.concatenate(states)


def labels(config: Config, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(which states' QPs the MPC solved [n] bool, its first input at those [k, 2]), each
    solve cold."""
    sc = config.scenario
    mpc = reference.reference_mpc(config.controller, config.body, sc.control_dt)
    solved, inputs = [], []
    for x in states:
        mpc.reset()
        u, _, ok, _ = mpc.solve(x)
        solved.append(ok)
        if ok:
            inputs.append(u)
    return np.array(solved), np.array(inputs)


def init_layers(key, sizes):
    layers = []
    for n_in, n_out in zip(sizes[:-1], sizes[1:]):
        key, sub = jax.random.split(key)
        layers.append((jax.random.normal(sub, (n_out, n_in)) / np.sqrt(n_in), jnp.zeros(n_out)))
    return layers


def fit(x, u, x_scale, u_scale, steps, seed):
    """Full-batch Adam (learning rate 3e-3 decaying to 3e-5) on the mean squared error of
    u / u_scale."""
    params = {
        "x_scale": jnp.asarray(x_scale),
        "u_scale": jnp.asarray(u_scale),
        "layers": init_layers(jax.random.PRNGKey(seed), [4, WIDTH, WIDTH, 2]),
    }

    def loss(layers):
        p = dict(params, layers=layers)
        pred = jax.vmap(lambda s: policy.forward(p, s))(x)
        return jnp.mean(((pred - u) / u_scale) ** 2)

    grad = jax.jit(jax.value_and_grad(loss))
    m = jax.tree.map(jnp.zeros_like, params["layers"])
    v = jax.tree.map(jnp.zeros_like, params["layers"])
    layers = params["layers"]
    for t in range(1, steps + 1):
        lr = 3e-3 * (1e-2 ** (t / steps))
        value, g = grad(layers)
        m = jax.tree.map(lambda a, b: 0.9 * a + 0.1 * b, m, g)
        v = jax.tree.map(lambda a, b: 0.999 * a + 0.001 * b * b, v, g)
        layers = jax.tree.map(
            lambda w, a, b, lr=lr, t=t: (
                w - lr * (a / (1 - 0.9**t)) / (jnp.sqrt(b / (1 - 0.999**t)) + 1e-8)
            ),
            layers,
            m,
            v,
        )
        if t % 1000 == 0:
            print(f"step {t}: loss {float(value):.3e}", flush=True)
    return dict(params, layers=layers)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=policy.shipped_weights())
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    config = Config().replace(scenario={"t_end": 3.0})
    start = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    visited = visited_states(config)
    x_scale = visited.std(axis=0)
    box = rng.uniform(-2, 2, size=(len(visited), 4)) * x_scale  # around upright
    states = np.concatenate([visited, box])
    solved, u = labels(config, states)
    x = states[solved]
    solved_source = np.array(["visited"] * len(visited) + ["box"] * len(box))[solved]
    print(
        f"{len(x)} labelled states ({len(visited)} visited + {len(box)} box, converged "
        f"solves only) in {time.perf_counter() - start:.0f} s",
        flush=True,
    )
    order = rng.permutation(len(x))
    test, train = order[: len(x) // 10], order[len(x) // 10 :]
    ctrl = config.controller
    u_scale = np.array([ctrl.input1_bounds[1], ctrl.input2_bounds[1]])
    params = fit(x[train], u[train], x_scale, u_scale, args.steps, args.seed)
    pred = np.asarray(jax.vmap(lambda s: policy.forward(params, s))(x[test]))
    error = np.abs(pred - u[test]) / u_scale
    for name in ("visited", "box"):
        e = error[solved_source[test] == name]
        print(
            f"held-out {name} states ({len(e)}), error / input bound: median "
            f"{np.median(e):.2e}, 99th percentile {np.percentile(e, 99):.2e}, "
            f"max {e.max():.2e}"
        )
    files = {"x_scale": np.asarray(x_scale, np.float32), "u_scale": u_scale.astype(np.float32)}
    for i, (w, b) in enumerate(params["layers"]):
        files[f"w{i}"], files[f"b{i}"] = np.asarray(w, np.float32), np.asarray(b, np.float32)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(args.out, convention=np.array(ctrl.convention), **files)
    print(
        f"wrote {args.out} ({args.out.stat().st_size} bytes) in {time.perf_counter() - start:.0f} s"
    )


if __name__ == "__main__":
    main()
