"""What one body-tile refill (``slots.refill_tiles``) costs on this machine's default device,
at a few slot counts, and the same for another version of the function (``--before``: a
``slots.py`` of another commit, e.g. ``git show REV:src/mjx_balance/rollout/slots.py``, or
an ``engine.py`` of a commit before the slots had a module of their own).

    python docs/scripts/refill_cost.py [--slots 32,4096,16384] [--bodies 101] [--before FILE]

The slots carry one number each (the refill's matching is what is timed; the gathers of a real
carry cost the same in both versions); half the slots are vacant, in whole tiles and single
slots; the offer is 4 x slots cells (the engine's refill buffer), their bodies in waves, a fifth
already used. Median of 20 compiled calls after a warm-up.
"""

from __future__ import annotations

import argparse
import importlib.util
import time

import jax
import jax.numpy as jnp
import numpy as np

from mjx_balance.rollout.engine import LANE_TILE
from mjx_balance.rollout.slots import Slots, refill_tiles


def module_from(path: str):
    """A slots.py (or engine.py) of another commit, imported inside this package (its relative
    imports)."""
    spec = importlib.util.spec_from_file_location("mjx_balance.rollout._before", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def case(S: int, n_bodies: int, rng):
    tile = LANE_TILE
    T = S // tile
    body = np.repeat(rng.integers(0, n_bodies, T), tile).astype(np.int32)
    cell = np.arange(S, dtype=np.int32) + 10 * S
    cell[rng.random(S) < 0.25] = -1  # single vacant slots
    cell[np.repeat(rng.random(T) < 0.25, tile)] = -1  # whole vacant tiles
    slots = Slots(carry={"x": jnp.zeros((S, 4))}, cell=jnp.asarray(cell),
                  force=jnp.zeros(S), n_push=jnp.zeros(S, jnp.int32),
                  k=jnp.ones(S, jnp.int32), body=jnp.asarray(body))
    R = 4 * S
    offer_body = np.sort(rng.integers(0, n_bodies, R)).astype(np.int32)
    rng.shuffle(offer_body.reshape(-1, max(1, R // 8)))  # waves: runs of bodies, not sorted
    args = (slots, {"x": jnp.zeros((n_bodies, 4))}, jnp.asarray(rng.random(R) < 0.2),
            slots.cell < 0, jnp.arange(R, dtype=jnp.int32), jnp.ones(R), jnp.ones(R, jnp.int32))
    kwargs = dict(starts={"x": jnp.zeros((R, 4))}, refill_body=jnp.asarray(offer_body))
    return args, kwargs


def timed(fn, args, kwargs) -> float:
    call = jax.jit(lambda *a: fn(*a, **kwargs, tile=LANE_TILE))
    jax.block_until_ready(call(*args))
    times = []
    for _ in range(20):
        t0 = time.perf_counter()
        jax.block_until_ready(call(*args))
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--slots", default="32,4096,16384")
    p.add_argument("--bodies", type=int, default=101)
    p.add_argument("--before", default=None)
    args = p.parse_args()
    versions = {"now": refill_tiles}
    if args.before:
        versions["before"] = module_from(args.before).refill_tiles
    print(f"device: {jax.devices()[0].device_kind}; {args.bodies} bodies, tiles of {LANE_TILE}")
    for S in (int(s) for s in args.slots.split(",")):
        a, k = case(S, args.bodies, np.random.default_rng(0))
        took = {name: fn(*a, **k, tile=LANE_TILE) for name, fn in versions.items()}
        line = ", ".join(f"{name} {1e3 * timed(fn, a, k):.3f} ms"
                         for name, fn in versions.items())
        counts = ", ".join(f"{name} {int((np.asarray(t[0].cell) >= 0).sum())}"
                           for name, t in took.items())
        print(f"{S} slots, {4 * S} offered: {line} a refill (busy slots after it: {counts})")


if __name__ == "__main__":
    main()
