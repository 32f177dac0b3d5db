"""Balance controllers behind one interface: the built-in MPC's peers and a user's own
(docs/model.md, "Bring your own controller").

A controller is a :class:`Controller`: a :class:`Law` (pure JAX functions, fixed under jit)
and its parameters (a pytree of arrays, traced: every body of a cohort has its own, and one
compiled program serves them all). Each control period the closed loop calls

    u, state, status = law.act(params, x, state)

with x [4] the state the controller sees in its convention (``controller.convention``: the
measurement ``scenario.controller_delay`` old, predicted to the instant with
``controller.delay_compensation``), ``state`` its own carried pytree (``law.init(params)`` at
the start of every scenario) and ``u`` [2] the convention's inputs. The loop then limits u to
the body's input bounds and rate limit (the motors' strength, the same for every controller),
holds it as motor torques for the period and folds ``status`` into the solver columns
(``nonconverged_solves``, ``admm_iterations``, ``max_residual``). A non-finite u ends the
scenario as diverged, as for the MPC.

``controller.kind`` names the controller: ``"mpc"`` (the default: the condensed QP solved by
``admm.py`` on the batched path and OSQP in the reference, with its certificate for the early
stop), ``"lqr"``, ``"pd"`` (:func:`lqr`, :func:`pd`) or ``"package.module:factory"``, a
function ``factory(config, **options) -> Controller`` (``options``: the
``[controller.options]`` table). ``act`` and ``init`` must be module-level functions that
read everything a body changes from ``params``: two bodies' controllers then have equal laws
and share one compiled program.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import Any, Callable, NamedTuple

import numpy as np
import scipy.linalg

from ..model.linear import S, linear_model, mass_gravity_abs
from ..model.params import Config, ParameterError


class Status(NamedTuple):
    """What a controller reports of one period's computation (counted into the summary)."""

    converged: Any  # bool []: False counts a non-converged solve
    iterations: Any  # int32 []: iterations run (0 for a closed-form law)
    residual: Any  # float []: the solver's residual (-inf: none)


def solved(xp: Any, dtype: Any) -> Status:
    """The status of a closed-form law: converged, no iterations, no residual."""
    return Status(xp.asarray(True), xp.asarray(0, xp.int32), xp.asarray(-np.inf, dtype))


class Law(NamedTuple):
    """A controller's functions: ``init(params) -> state`` and
    ``act(params, x, state) -> (u, state, Status)`` (module docstring); pure JAX, so that
    they jit and vmap with the physics."""

    name: str
    init: Callable[[Any], Any]
    act: Callable[[Any, Any, Any], tuple[Any, Any, Status]]


class Controller(NamedTuple):
    """A :class:`Law` with its parameters: a pytree of numpy arrays (float64), cast to the
    run's dtype by the closed loop."""

    law: Law
    params: Any


def cast(params: Any, dtype: Any) -> Any:
    """``params`` as JAX arrays, the floating ones in ``dtype`` (the run's)."""
    import jax
    import jax.numpy as jnp

    def one(value: Any) -> Any:
        array = np.asarray(value)
        floating = np.issubdtype(array.dtype, np.floating)
        return jnp.asarray(array, dtype) if floating else jnp.asarray(array)

    return jax.tree.map(one, params)


def limited(xp: Any, u: Any, lower: Any, upper: Any, first: Any = None) -> Any:
    """A controller's input ``u`` [2] within the body's input bounds [lower, upper] and, with
    ``first`` ([2, 2], ``qp.rate_bounds``), the rate limit: what the loop holds, on the
    batched path (``rollout.kernel.act``) and in the reference alike (``xp``: numpy or
    jax.numpy)."""
    if first is not None:
        lower, upper = xp.maximum(lower, first[0]), xp.minimum(upper, first[1])
    return xp.minimum(xp.maximum(u, lower), upper)


def no_state(params: Any) -> tuple:
    """The carried state of a law that keeps none."""
    return ()


def feedback(params: Any, x: Any, state: Any) -> tuple[Any, Any, Status]:
    """Linear state feedback u = -K x (``params["gain"]`` [2, 4]), for :func:`lqr` and
    :func:`pd`; the loop saturates u at the body's bounds."""
    import jax.numpy as jnp

    gain = params["gain"]
    return -(gain @ x), state, solved(jnp, gain.dtype)


FEEDBACK = Law("feedback", no_state, feedback)


def lqr(config: Config) -> Controller:
    """The infinite-horizon discrete LQR of the MPC's own linearisation and weights: the
    control period's zero-order-hold model (``linear.linear_model``) with Q = diag(q_diag),
    R = diag(r_diag), from the discrete Riccati equation; saturated at the input bounds by
    the loop. Without bounds binding, the MPC with an infinite horizon is this law."""
    ctrl = config.controller
    lm = linear_model(config.body, ctrl.convention, config.scenario.control_dt)
    Q, R = np.diag(ctrl.q_diag), np.diag(ctrl.r_diag)
    P = scipy.linalg.solve_discrete_are(lm.A, lm.B, Q, R)
    gain = np.linalg.solve(R + lm.B.T @ P @ lm.B, lm.B.T @ P @ lm.A)
    return Controller(FEEDBACK._replace(name="lqr"), {"gain": gain})


def pd(config: Config) -> Controller:
    """A PD at each joint with gravity compensation, designed on the linearised body
    (M q'' = G_j q + tau in joint coordinates, docs/model.md "Linear model and
    discretisation"): the joint torques -G_j q - Kp q - Kd dq, where -G_j q cancels gravity's
    torque, and each joint is critically damped at twice the falling rate of the uncontrolled
    body, w = 2 sqrt(max eig(M_j^-1 G_j)): Kp_i = M_ii w^2, Kd_i = 2 M_ii w (M_ii: the joint's
    own inertia). The torques map to the convention's inputs; the loop saturates them at the
    input bounds."""
    ctrl = config.controller
    lm = linear_model(config.body, ctrl.convention, config.scenario.control_dt)
    M_abs, G_abs, _ = mass_gravity_abs(config.body)
    M, G = S.T @ M_abs @ S, S.T @ G_abs @ S  # joint coordinates (linear.py)
    rate = float(np.sqrt(np.max(np.linalg.eigvals(np.linalg.solve(M, G)).real)))
    w = 2.0 * rate
    Kp, Kd = np.diag(np.diag(M) * w**2), np.diag(2.0 * np.diag(M) * w)
    to_q = np.linalg.solve(S, lm.P)  # q = to_q y (the convention's positions y)
    joint_gain = np.hstack([(Kp + G) @ to_q, Kd @ to_q])  # tau_joint = -joint_gain x
    gain = np.linalg.solve(lm.torque_map, joint_gain)  # u = torque_map^-1 tau_joint
    return Controller(FEEDBACK._replace(name="pd"), {"gain": gain})


BUILT_IN: dict[str, Callable[[Config], Controller]] = {"lqr": lqr, "pd": pd}  # (and "mpc")


def importable(name: str) -> Any:
    """Module ``name``, from the Python path or else from the current folder (as ``python -m``
    finds a module there; a console script's path does not hold it)."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        here = os.getcwd()
        if exc.name != name.partition(".")[0] or here in sys.path:
            raise
        sys.path.append(here)
        return importlib.import_module(name)


def factory_of(kind: str) -> Callable[..., Controller]:
    """The factory ``kind`` names ("lqr", "pd" or "package.module:factory", a form the
    configuration's check has made sure of); ParameterError in one line when it cannot be
    found."""
    if kind in BUILT_IN:
        return BUILT_IN[kind]
    module_name, _, name = kind.partition(":")
    try:
        module = importable(module_name)
    except ImportError as exc:
        raise ParameterError(
            f"controller.kind {kind!r}: cannot import {module_name} ({exc})"
        ) from None
    target: Any = module
    for part in name.split("."):
        target = getattr(target, part, None)
    if not callable(target):
        raise ParameterError(f"controller.kind {kind!r}: {module_name} has no function {name}")
    return target


def controller_of(config: Config) -> Controller | None:
    """The configuration's controller (None: the MPC, which the closed loops run natively);
    its factory called with ``[controller.options]``. ParameterError in one line when the
    factory fails or returns something other than a Controller."""
    ctrl = config.controller
    if ctrl.kind == "mpc":
        return None
    factory = factory_of(ctrl.kind)
    options = dict(ctrl.options)
    try:
        made = factory(config, **options) if options else factory(config)
    except ParameterError:
        raise
    except Exception as exc:  # a user's factory: its failure named, in one line
        raise ParameterError(
            f"controller.kind {ctrl.kind!r}: the factory failed: {type(exc).__name__}: {exc}"
        ) from None
    if not isinstance(made, Controller) or not isinstance(made.law, Law):
        raise ParameterError(
            f"controller.kind {ctrl.kind!r}: the factory returned {type(made).__name__}, "
            "not mjx_balance.control.law.Controller"
        )
    check_traced(made, ctrl.kind)
    return made


def check_traced(made: Controller, kind: str) -> None:
    """Trace ``init`` and ``act`` once on a state of shape [4] (``jax.eval_shape``: nothing
    compiles or runs) and refuse in one line what the loop cannot carry: a law JAX cannot
    trace (e.g. Python ``if`` on the state), an input that is not 2 numbers, a state whose
    structure, shapes or dtypes ``act`` changes, a Status that is not three scalars."""
    import jax
    import jax.numpy as jnp

    params = cast(made.params, jnp.float32)
    x = jax.ShapeDtypeStruct((4,), jnp.float32)

    def fail(what: str) -> ParameterError:
        return ParameterError(
            f'controller.kind {kind!r}: {what} (docs/model.md, "Bring your own controller")'
        )

    try:
        state = jax.eval_shape(made.law.init, params)
        u, after, status = jax.eval_shape(made.law.act, params, x, state)
    except Exception as exc:  # a user's law: why JAX cannot trace it, in one line
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise fail(f"JAX cannot trace its law: {type(exc).__name__}: {first}") from None
    if tuple(u.shape) not in ((2,), (1, 2), (2, 1)):
        raise fail(f"act returns u of shape {tuple(u.shape)}, not 2 inputs")

    def described(tree: Any) -> list:  # (the structure, then each leaf's shape and dtype)
        leaves, structure = jax.tree.flatten(tree)
        return [str(structure)] + [(v.shape, v.dtype) for v in leaves]

    if described(after) != described(state):
        raise fail("act returns a state of another structure, shape or dtype than init's")
    if not isinstance(status, Status) or any(jnp.shape(v) != () for v in status):
        raise fail("act's third result must be a law.Status of three scalars")


def kind_of(controller: Any) -> str:
    """``controller`` (a kind's name, or a module-level factory function) as the string
    ``controller.kind`` records, so that a folder's configuration names it."""
    if isinstance(controller, str):
        return controller
    module, name = getattr(controller, "__module__", None), getattr(controller, "__qualname__", "")
    if not callable(controller) or not module or "<" in name:
        raise ParameterError(
            "controller: give a kind ('mpc', 'lqr', 'pd', 'package.module:factory') or a "
            f"module-level factory function, got {controller!r}"
        )
    return f"{module}:{name}"
