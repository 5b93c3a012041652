"""States of a cross-check: random states plus edge states, reproducible from a seed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mbctl.robots.model_pair import Robot


@dataclass(frozen=True)
class Sampling:
    """How random states are drawn.

    Limited hinge and slide joints are uniform within their MuJoCo ``range``; unlimited hinges
    uniform in [-pi, pi]; free and ball joints get a uniform random unit quaternion.

    Attributes:
        position_range_m: Free-joint positions uniform in [-r, r]^3 [m]; unlimited slides too.
        velocity_std: Standard deviation of each velocity coordinate [rad/s] or [m/s].
        torque_std: Standard deviation of each generalized force [N m] or [N].
        acceleration_std: Standard deviation of each acceleration for inverse dynamics
            [rad/s^2] or [m/s^2].
    """

    position_range_m: float = 1.0
    velocity_std: float = 1.0
    torque_std: float = 10.0
    acceleration_std: float = 10.0


class States(NamedTuple):
    """States of a cross-check, in Pinocchio's convention.

    Attributes:
        q: Configurations (n, nq).
        v: Velocities (n, nv).
        tau: Generalized forces for forward dynamics (n, nv) [N m] or [N].
        a: Accelerations for inverse dynamics (n, nv) [rad/s^2] or [m/s^2].
        kinds: Kind of each state ("random", "zero velocity", ...), length n.
    """

    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    a: np.ndarray
    kinds: tuple[str, ...]


def sample_states(robot: Robot, n_states: int, seed: int, sampling: Sampling = Sampling()) -> States:
    """``n_states`` random states plus edge states, reproducible from ``seed``.

    Edge states (placed first): neutral configuration at zero velocity; a random configuration
    at zero velocity; and, if the robot has limited joints, all limited hinges and slides at their
    lower limits, then at their upper limits (other joints random, velocity random).

    Args:
        robot: The model pair; limits come from the MuJoCo model (the plant).
        n_states: Number of random states (>= 0).
        seed: Seed of ``numpy.random.default_rng``.
        sampling: Ranges and scales of the random draws.

    Returns:
        The states, in Pinocchio's convention.
    """
    m = robot.mj_model
    rng = np.random.default_rng(seed)
    jid_at = {int(adr): j for j, adr in enumerate(m.jnt_qposadr)}  # plant qpos address -> joint id
    jids = {j.name: jid_at[j.qposadr] for j in robot.joints.values()}
    limited = [
        (j.idx_q, jids[j.name])
        for j in robot.joints.values()
        if j.kind in ("hinge", "slide") and m.jnt_limited[jids[j.name]]
    ]
    kinds = ["neutral, v = 0", "zero velocity"]
    if limited:
        kinds += ["lower limits", "upper limits"]
    kinds += ["random"] * n_states
    n, r = len(kinds), sampling.position_range_m
    q = np.tile(robot.neutral_q(), (n, 1))
    for j in robot.joints.values():  # one draw per joint for all states at once
        at = j.idx_q
        if j.kind in ("free", "ball"):
            if j.kind == "free":
                q[:, at : at + 3] = rng.uniform(-r, r, (n, 3))
                at += 3
            quat_xyzw = rng.normal(size=(n, 4))  # isotropic Gaussian -> uniform on S^3
            q[:, at : at + 4] = quat_xyzw / np.linalg.norm(quat_xyzw, axis=1, keepdims=True)
        elif m.jnt_limited[jids[j.name]]:
            lo, hi = m.jnt_range[jids[j.name]]
            q[:, at] = rng.uniform(lo, hi, n)
        elif j.kind == "hinge":
            q[:, at] = rng.uniform(-np.pi, np.pi, n)
        else:
            q[:, at] = rng.uniform(-r, r, n)
    q[0] = robot.neutral_q()
    for iq, jid in limited:
        q[2, iq], q[3, iq] = m.jnt_range[jid]
    v = rng.normal(0, sampling.velocity_std, (n, robot.nv))
    v[:2] = 0.0
    tau = rng.normal(0, sampling.torque_std, (n, robot.nv))
    a = rng.normal(0, sampling.acceleration_std, (n, robot.nv))
    return States(q, v, tau, a, tuple(kinds))
