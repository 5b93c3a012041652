"""Small Pinocchio models built in code for the task tests, and the finite differences they use.

Test modules import the helpers: ``from tests.control.tasks.conftest import ARM, fd_jacobian``.

* ``ARM``: a fixed-base arm, yaw, shoulder pitch, a slide and an elbow pitch (4 dofs), with the
  frames ``elbow`` and ``tip`` (the tip rotated and off the joint axes).
* ``FLOATING``: a free-flyer torso with an arm (ball shoulder, elbow hinge; frame ``hand``) and a
  leg (hip roll, knee pitch; frame ``foot``), frame ``chest`` on the torso: 6 + 3 + 1 + 2 = 12 dofs.
* ``FLOATING_HINGES``: the same with the ball replaced by a hinge (every joint dof is 1-dof, so the
  posture Jacobian is ``diag(mask)``): 10 dofs.

Every body has a mass off its joint axis, so the CoM and the momentum depend on every joint.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from mbctl.control.tasks import DynamicsState, KinematicState, Task, TaskStack

#: Finite-difference step on the manifold [rad or m]: central differences then err ~1e-10.
FD_STEP = 1e-6


def _body(model: pin.Model, joint_id: int, mass: float, com: tuple[float, float, float]) -> None:
    """A box-like body of ``mass`` [kg] with its CoM at ``com`` [m] in the joint's frame."""
    inertia = pin.Inertia(mass, np.array(com), np.diag([0.02, 0.03, 0.01]) * mass)
    model.appendBodyToJoint(joint_id, inertia, pin.SE3.Identity())


def _frame(model: pin.Model, name: str, joint_id: int, placement: pin.SE3) -> None:
    model.addFrame(pin.Frame(name, joint_id, placement, pin.FrameType.OP_FRAME))


def _placement(xyz: tuple[float, float, float], rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> pin.SE3:
    return pin.SE3(pin.rpy.rpyToMatrix(np.array(rpy)), np.array(xyz))


def arm_model() -> pin.Model:
    """The fixed-base arm (nq = nv = 4)."""
    model = pin.Model()
    model.name = "arm"
    yaw = model.addJoint(0, pin.JointModelRZ(), _placement((0.0, 0.0, 0.1)), "yaw")
    _body(model, yaw, 1.0, (0.0, 0.02, 0.1))
    shoulder = model.addJoint(yaw, pin.JointModelRY(), _placement((0.0, 0.0, 0.2)), "shoulder")
    _body(model, shoulder, 0.8, (0.15, 0.0, 0.01))
    slide = model.addJoint(shoulder, pin.JointModelPX(), _placement((0.3, 0.0, 0.0)), "slide")
    _body(model, slide, 0.3, (0.02, 0.01, 0.0))
    elbow = model.addJoint(slide, pin.JointModelRY(), _placement((0.05, 0.0, 0.0)), "elbow")
    _body(model, elbow, 0.5, (0.12, -0.01, 0.0))
    _frame(model, "elbow", elbow, pin.SE3.Identity())
    _frame(model, "tip", elbow, _placement((0.25, 0.02, 0.01), (0.3, -0.2, 0.5)))
    return model


def floating_model(ball: bool = True) -> pin.Model:
    """The free-flyer torso with an arm and a leg (see the module docstring)."""
    model = pin.Model()
    model.name = "floating" if ball else "floating_hinges"
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    _body(model, root, 5.0, (0.01, 0.0, 0.05))
    _frame(model, "chest", root, _placement((0.05, 0.0, 0.3), (0.0, 0.2, 0.0)))
    shoulder_joint = pin.JointModelSpherical() if ball else pin.JointModelRX()
    shoulder = model.addJoint(root, shoulder_joint, _placement((0.0, 0.15, 0.25)), "shoulder")
    _body(model, shoulder, 1.0, (0.0, 0.0, -0.12))
    elbow = model.addJoint(shoulder, pin.JointModelRY(), _placement((0.0, 0.0, -0.25)), "elbow")
    _body(model, elbow, 0.6, (0.1, 0.0, 0.0))
    _frame(model, "hand", elbow, _placement((0.22, 0.0, -0.02), (0.1, 0.4, -0.3)))
    hip = model.addJoint(root, pin.JointModelRX(), _placement((0.0, -0.1, -0.05)), "hip")
    _body(model, hip, 1.5, (0.0, 0.0, -0.15))
    knee = model.addJoint(hip, pin.JointModelRY(), _placement((0.0, 0.0, -0.3)), "knee")
    _body(model, knee, 1.0, (0.01, 0.0, -0.14))
    _frame(model, "foot", knee, _placement((0.03, 0.0, -0.3)))
    return model


ARM = arm_model()
FLOATING = floating_model(ball=True)
FLOATING_HINGES = floating_model(ball=False)
MODELS = (ARM, FLOATING, FLOATING_HINGES)


def random_q(model: pin.Model, rng: np.random.Generator, scale: float = 0.5) -> np.ndarray:
    """A configuration (nq,) ``neutral ⊕ scale N(0, 1)`` (unit quaternions, the base off the origin)."""
    return pin.integrate(model, pin.neutral(model), scale * rng.standard_normal(model.nv))


def joint_mask(model: pin.Model) -> np.ndarray:
    """(nv,) 1.0 on every dof but the free flyer's (the first six of the floating models)."""
    mask = np.ones(model.nv)
    if model.joints[1].shortname() == "JointModelFreeFlyer":
        mask[:6] = 0.0
    return mask


def fd_jacobian(error: Callable[[np.ndarray], np.ndarray], model: pin.Model, q: np.ndarray,
                h: float = FD_STEP) -> np.ndarray:
    """``d error / dq`` (k, nv) by central differences on the manifold: ``error(q ⊕ ±h e_i)``."""
    columns = []
    for i in range(model.nv):
        dq = np.zeros(model.nv)
        dq[i] = h
        e_plus = np.array(error(pin.integrate(model, q, dq)))
        e_minus = np.array(error(pin.integrate(model, q, -dq)))
        columns.append((e_plus - e_minus) / (2 * h))
    return np.column_stack(columns)


def kinematic_error(task: Task, model: pin.Model) -> Callable[[np.ndarray], np.ndarray]:
    """``q -> task.compute_error`` at a fresh kinematic state (what ``fd_jacobian`` differentiates)."""
    return lambda q: task.compute_error(KinematicState(model, q))


def fd_drift(task: Task, model: pin.Model, q: np.ndarray, v: np.ndarray, h: float = FD_STEP) -> np.ndarray:
    """``d/dt (J(q) v)`` (k,) at constant v, along ``q(t) = q ⊕ t v``: central differences of J."""
    J_plus, _ = task.jacobian_and_drift(DynamicsState(model, pin.integrate(model, q, h * v), v))
    J_minus, _ = task.jacobian_and_drift(DynamicsState(model, pin.integrate(model, q, -h * v), v))
    return (J_plus - J_minus) @ v / (2 * h)


def inf_norm(a: np.ndarray) -> float:
    """``max |a_ij|`` (0 for an empty array)."""
    return float(np.max(np.abs(a), initial=0.0))


def velocity_objective(task: Task, state: KinematicState) -> tuple[np.ndarray, np.ndarray, float]:
    """``(H, c, mu)`` of a stack holding ``task`` alone (the IK's assembly)."""
    nv = state.nv
    H, c = np.full((nv, nv), np.nan), np.full(nv, np.nan)
    mu = TaskStack(nv, [task]).velocity_objective(state, H, c)
    return H, c, mu


def expected_velocity_objective(task: Task, e: np.ndarray,
                                J: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(W^T W, -W^T r, lm |r|^2)`` with ``W = diag(cost) J`` and ``r = -gain diag(cost) e``."""
    W = task.cost[:, None] * J
    r = -task.gain * task.cost * e
    return W.T @ W, -W.T @ r, task.lm_damping * float(r @ r)


def acceleration_objective(task: Task, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
    """``(H, c)`` of a stack holding ``task`` alone (the inverse dynamics' assembly)."""
    nv = state.nv
    H, c = np.full((nv, nv), np.nan), np.full(nv, np.nan)
    TaskStack(nv, [task]).acceleration_objective(state, H, c)
    return H, c


def expected_acceleration_objective(task: Task, J: np.ndarray, drift: np.ndarray,
                                    a_des: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(W^T W, -W^T r)`` with ``W = diag(cost) J`` and ``r = diag(cost) (a_des - Jdot v)``."""
    W = task.cost[:, None] * J
    r = task.cost * (a_des - drift)
    return W.T @ W, -W.T @ r


def acceleration_rows(task: Task, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
    """The task's own ``(W_t (k, nv), r_t (k,))`` at the acceleration level."""
    W_t, r_t = np.full((task.k, state.nv), np.nan), np.full(task.k, np.nan)
    task.write_acceleration_rows(state, W_t, r_t)
    return W_t, r_t


def velocity_rows(task: Task, state: KinematicState) -> tuple[np.ndarray, np.ndarray]:
    """The task's unweighted active rows ``(J_e[a], e[a])`` as it writes them (maybe both negated)."""
    n = len(task.active_rows())
    J_out, e_out = np.full((n, state.nv), np.nan), np.full(n, np.nan)
    task.write_velocity_rows(state, J_out, e_out)
    return J_out, e_out
