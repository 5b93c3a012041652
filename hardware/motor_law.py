"""Motor gains a plant keeps stable when it applies the motor law once per state period, a period late.

A robot's motors apply ``tau = kp (q* - q) + kd (dq* - dq)``. The G1's own drivers run that law
far faster than its 500 Hz state, where any ``kp, kd > 0`` are stable as in continuous time. A
plant that applies it once per state period ``T``, from the state a period old, is not so
forgiving: Unitree's simulator computes the law when a LowCmd arrives, from the sensors of the
step before (MuJoCo computes sensors before it integrates), and its explicit step holds the
torque for ``T``. Linearised about a pose, with ``W`` the motors' inverse inertia (n, n) [1/(kg m^2)]
(the base free, the feet held still) and ``K``, ``D`` the diagonal gains, that is

    v[k+1] = v[k] - T W (K x[k-1] + D v[k-1]),    x[k+1] = x[k] + T v[k+1]

(semi-implicit Euler, as MuJoCo), stable when every eigenvalue of its (4n, 4n) matrix has
``|z| < 1``. The joints couple: on the G1 at 5 ms the least stable modes are both shoulder yaws
with the wrists, and the pelvis turning between both hip pitches and the waist pitch. With
Menagerie's G1 position gains (kp 500 N m/rad, kv 4.5-16 N m s/rad) the largest ``|z|`` is 1.23
at the G1's 2 ms and 2.1 at Unitree's default 5 ms. At 5 ms the G1 held at its stand pose by
those gains falls in Unitree's simulator (the ankles oscillating); at 2 ms the joints' friction
(0.1-0.2 N m in Unitree's model) holds the small motions still. One joint alone matches the
recurrence in MuJoCo to the third digit of ``|z|`` (tests/hardware/test_motor_law.py).

:func:`stable_gains` keeps the gains when the law is stable with a gain margin of
:data:`GAIN_MARGIN` (both gains that many times larger, as the inertia that many times smaller,
still stable); otherwise it lowers both gains of the joints that move most in the least stable
mode by :data:`GAIN_STEP` (the ratio kd/kp kept), and looks again. A mode that only drifts
(``z = 1``: a motor without stiffness) is not unstable. At 5 ms it lowers the G1's hips, knees,
waist and arms to kp 43-205 N m/rad (kd 0.6-3.7); Unitree's own G1 examples use kp 40-150 and kd 1-2.

Written here because no library states the stability of a delayed explicit motor law on a
coupled multibody model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mbctl.hardware.motor_commands import MotorGains
from mbctl.robots.model_pair import Robot
from mbctl.unitree.motors import MotorMap

#: Gains kept stable with both multiplied by this: the plant's inertia may be 20 % below the model's.
#: More costs the stiffness that holds a robot up against gravity: on Unitree's simulator at 5 ms,
#: holding the G1's stand by position targets, 1.25 leaves 0.014 rad of sag, 1.5 0.067 rad (hip
#: pitch), and 2 lowers the hips to 34 N m/rad and the robot falls.
GAIN_MARGIN = 1.25
#: Each step lowers the gains of the joints in the least stable mode by this factor.
GAIN_STEP = 0.8
#: A joint is in the mode when it moves at least this share of the joint that moves most.
MODE_SHARE = 0.5
#: The most steps (0.8^200 ~ 4e-20: no gains left).
MAX_STEPS = 200
#: Eigenvalues this close to 1 are a free position's drift (a double root there, which eig resolves to
#: ~1e-8), not an instability (``|z| = 1 + 1e-6`` would double in 700,000 periods).
DRIFT_TOL = 1e-6


def inverse_inertia(robot: Robot, q: npt.ArrayLike, idx_v: npt.ArrayLike,
                    fixed_frames: Sequence[str] = ()) -> np.ndarray:
    """The inverse inertia ``W`` (n, n) of the dofs ``idx_v`` at ``q``: acceleration per torque.

    ``W = S (M^-1 - M^-1 J^T (J M^-1 J^T)^+ J M^-1) S^T``: the other dofs (the floating base
    too) free, the frames ``fixed_frames`` held still (``J`` their stacked 6D Jacobians; none: the
    robot in the air), armature included.

    Args:
        robot: The model pair (Pinocchio's model).
        q: The configuration (nq,), Pinocchio convention.
        idx_v: The dofs (indices into v).
        fixed_frames: Frames held still (the feet of a robot standing).
    """
    minv = np.linalg.inv(robot.mass_matrix(q))
    if fixed_frames:
        jac = np.vstack([robot.jacobian(f, q, "local") for f in fixed_frames])
        mj = minv @ jac.T
        minv = minv - mj @ np.linalg.pinv(jac @ mj, rcond=1e-10) @ mj.T
    idx = np.asarray(idx_v, dtype=int)
    return minv[np.ix_(idx, idx)]


def least_stable_mode(inv_inertia: np.ndarray, kp: np.ndarray, kd: np.ndarray,
                      period_s: float) -> tuple[float, np.ndarray]:
    """The largest ``|z|`` of the delayed law (module docstring) and how much each joint moves in it.

    Args:
        inv_inertia: ``W`` (n, n) [1/(kg m^2)].
        kp: Stiffness (n,) [N m/rad] (0: none).
        kd: Damping (n,) [N m s/rad].
        period_s: The period [s] at which the law is applied.

    Returns:
        ``|z|`` (drift modes, ``z = 1``, left out; 0 if none is left) and the joints' position
        amplitudes (n,) in that mode (their velocities' when ``kp`` is 0 everywhere).
    """
    n, t = kp.size, period_s
    a = np.zeros((4 * n, 4 * n))  # state: x, v, x a period ago, v a period ago
    eye = np.eye(n)
    a[n:2 * n, n:2 * n] = eye
    a[n:2 * n, 2 * n:3 * n] = -t * inv_inertia * kp  # W @ diag(kp)
    a[n:2 * n, 3 * n:] = -t * inv_inertia * kd
    a[:n, :n] = eye
    a[:n] += t * a[n:2 * n]
    a[2 * n:3 * n, :n] = eye
    a[3 * n:, n:2 * n] = eye
    values, vectors = np.linalg.eig(a)
    size = np.abs(values)
    size[np.abs(values - 1.0) < DRIFT_TOL] = 0.0
    i = int(np.argmax(size))
    part = vectors[:n, i] if np.any(kp > 0) else vectors[n:2 * n, i]
    return float(size[i]), np.abs(part)


def stable_gains(inv_inertia: np.ndarray, kp: npt.ArrayLike, kd: npt.ArrayLike,
                 period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Gains (kp, kd) whose delayed law at ``period_s`` is stable with :data:`GAIN_MARGIN`.

    Gains with that margin are kept; otherwise the joints of the least stable mode are lowered
    (module docstring) until it has. NaN (a motor without gains) stays NaN and counts as none.

    Args:
        inv_inertia: ``W`` (n, n) [1/(kg m^2)] (:func:`inverse_inertia`).
        kp: Stiffness (n,) [N m/rad], >= 0 or NaN.
        kd: Damping (n,) [N m s/rad], >= 0 or NaN.
        period_s: The period [s] at which the plant applies the law.
    """
    kp_in, kd_in = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
    given = np.isfinite(kp_in) & np.isfinite(kd_in)
    k, d = np.where(given, kp_in, 0.0), np.where(given, kd_in, 0.0)
    for _ in range(MAX_STEPS):
        size, part = least_stable_mode(inv_inertia, GAIN_MARGIN * k, GAIN_MARGIN * d, period_s)
        if size < 1.0:
            break
        lower = given & (part >= MODE_SHARE * part[given].max())
        k[lower] *= GAIN_STEP
        d[lower] *= GAIN_STEP
    return np.where(given, k, kp_in), np.where(given, d, kd_in)


@dataclass(frozen=True)
class StableGains:
    """What :func:`stabilize` found.

    Attributes:
        gains: The position and velocity targets' gains to send (motor order).
        damping_kd: The damping command's kd (n,) [N m s/rad].
        lowered: Per joint whose gains were lowered: gain (``kp``, ``kd``, ``damping_kd``) ->
            (given, sent); empty when every gain was kept.
    """

    gains: MotorGains
    damping_kd: np.ndarray
    lowered: dict[str, dict[str, tuple[float, float]]]


def stabilize(robot: Robot, motors: MotorMap, gains: MotorGains, damping_kd: np.ndarray, period_s: float,
              q_joints: np.ndarray, feet: Sequence[str] = ()) -> StableGains:
    """The motors' gains and damping made stable for a law applied once per ``period_s``, a period late.

    The targets' gains are judged with ``feet`` on the ground (the robot stands at connect), the
    damping command's in the air (it is sent to a robot that may be falling).

    Args:
        robot: The model pair.
        motors: The motor map.
        gains: The gains given (motor order; NaN where a motor has none).
        damping_kd: The damping command's kd given (n,).
        period_s: The state period [s].
        q_joints: The motors' joint angles (n,) [rad] now (the inertia depends on them).
        feet: The frames on the ground now.
    """
    q = robot.neutral_q()
    q[motors.idx_q] = q_joints
    kp, kd = stable_gains(inverse_inertia(robot, q, motors.idx_v, feet), gains.kp, gains.kd, period_s)
    _, damping = stable_gains(inverse_inertia(robot, q, motors.idx_v), np.zeros(motors.n), damping_kd,
                              period_s)
    lowered: dict[str, dict[str, tuple[float, float]]] = {}
    pairs = (("kp", gains.kp, kp), ("kd", gains.kd, kd), ("damping_kd", damping_kd, damping))
    for name, given, sent in pairs:
        for i in np.flatnonzero(np.isfinite(given) & (sent != given)):
            lowered.setdefault(motors.joints[i], {})[name] = (float(given[i]), float(sent[i]))
    return StableGains(MotorGains(kp, kd), damping, lowered)
