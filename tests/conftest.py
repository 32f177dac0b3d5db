"""Test configuration: float64 is available (jax_enable_x64); library code always names its dtype."""

import jax

jax.config.update("jax_enable_x64", True)
