"""The fingerprint of the shared-body engine's compiled call (its lowered program, before XLA
compiles it) for the study's configuration: two checkouts that print the same fingerprint run
the same program in ``sweep``, ``bench`` and the dense map, so a change elsewhere cannot have
made them faster or slower on the device.

    PYTHONPATH=CHECKOUT/src python docs/scripts/engine_program.py

Prints the package's path, the sha256 of the lowered program's text (first 16 hex digits) and
its length. Nothing is compiled.
"""

from __future__ import annotations

import hashlib

import jax
import jax.numpy as jnp

import mjx_balance as mb
from mjx_balance.rollout import BatchRunner
from mjx_balance.rollout.engine import Engine
from mjx_balance.rollout.slots import block


def main() -> None:
    engine = Engine(BatchRunner(mb.Config(), physics="mjx"))
    r = engine.runner

    def call(arrays, cert, slots, cell, force, push, init, body):
        return block(arrays, r.sensors, engine.static, cert, slots, refill_cell=cell,
                     refill_force=force, refill_push=push, refill_init=init, refill_body=body,
                     periods=engine.block, early_stop=engine.cert is not None,
                     packing=engine.packing, tile=engine.tile, lanes=engine.lanes)

    n = engine.refill * engine.n_devices
    shape = jax.ShapeDtypeStruct
    text = jax.jit(call, donate_argnums=(2,)).lower(
        engine.arrays, engine.cert, jax.eval_shape(engine._vacant, engine.arrays),
        shape((n,), jnp.int32), shape((n,), r.dtype), shape((n,), jnp.int32),
        shape((n, 4), r.dtype), shape((n,), jnp.int32)).as_text()
    print(mb.__file__, hashlib.sha256(text.encode()).hexdigest()[:16], len(text))


if __name__ == "__main__":
    main()
