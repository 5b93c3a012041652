"""Floating-base state from the IMU and the joint encoders, with feet in contact: a linear Kalman filter.

The robot measures its joints and its IMU, not where its base is. With a foot on the ground, the
foot does not move, so leg kinematics tie the base to it: this is the linear filter of Bledt et
al. (MIT Cheetah 3, IROS 2018), also used on humanoids.

Notation: W world (z up, x and y where the base started), B base, I IMU, F a foot frame, P the
foot's contact point. The IMU gives R_WI (its orientation filter), w_I (gyro) and the specific
force f_I (accelerometer); R_BI and p_BI are fixed by the model. So R_WB = R_WI R_BI^T and
w_B = R_BI w_I are measured; the filter estimates the rest.

State x = [p_WB, v_WB, p_WP1, ..., p_WPn] (3 + 3 + 3 n), all in W.

- Predict (the IMU drives it): a_W = R_WI f_I + g; p += v dt + a dt^2 / 2; v += a dt; feet stay,
  with a random walk that grows without bound for a foot out of contact.
- Correct, for each foot in contact: p_WP - p_WB = R_WB p_BP(q) (leg forward kinematics, base at the
  origin), and v_WB = -R_WB (v_BP(q, dq) + w_B x p_BP) (the contact point is at rest).

The model is linear in x, so the filter is exact for it (no linearization); R_WB enters only
through the measurements. Its terms have no cross-axis part: the prediction, the measurement rows
and every noise act on x, y and z alone, so the covariance is block-diagonal by world axis. The
filter keeps the state axis by axis, ``[X_x; X_y; X_z]`` with ``X_a = [p_WB, v_WB, p_WP1, ...,
p_WPn]_a`` (2 + n each), and corrects the three axes in one solve on that block-diagonal system:
the same estimate as the textbook filter in ``x``'s order (``P`` gives its covariance in that
order), on the Python calls of one small filter, where numpy's per-call cost is most of the work.

Position and yaw are unobservable: they stay where they started and drift only as much as the
feet slip. The height is observable through the starting assumption that the contact points
are on the ground (z = ``ground_z_m``); a foot that lands takes its height from the base's, so
each step can carry an error of the height on (a sole that rolls about its edge moves the point
assumed still). On flat ground, ``ground_noise_m`` adds a measurement: each foot in contact is at
``ground_z_m``, with that standard deviation: rows in the z block alone, after the legs' rows, in
the same solve (so z's block of the covariance then differs from x's and y's). An update takes
50 us with the ground's rows or without (median over a humanoid's readings replayed, e.g. the G1's,
two feet; where x and y shared one (2 + n) covariance and z had its own, two corrections took 68-70
us with them, one 45-50 us without).

Out of scope: the IMU's lever arm (its centripetal acceleration, below 0.01 m/s^2 for a standing
robot), accelerometer bias, contact detection (the feet in contact are given: ``set_contacts``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.linalg.lapack import dposv

from mbctl.control.estimation.exceptions import EstimatorError
from mbctl.robots.fastmath import all_finite, cross3, quat_xyzw_to_matrix
from mbctl.robots.interface import BASE_LINEAR_VELOCITY, BASE_POSITION, Proprioception
from mbctl.robots.model_pair import Robot


@dataclass(frozen=True)
class LegKinematicsNoise:
    """Standard deviations of the filter's noise models.

    Attributes:
        accel_m_s2: Accelerometer white noise [m/s^2] (drives the velocity).
        foot_slip_m_s: Random walk of a foot in contact [m/s^0.5] (how far it may slip).
        foot_swing_m_s: Random walk of a foot in the air [m/s^0.5] (large: it goes anywhere).
        kinematics_m: Error of the leg kinematics p_BP [m] (encoders, model).
        leg_velocity_m_s: Error of the base velocity measured through a leg [m/s].
    """

    accel_m_s2: float = 0.5
    foot_slip_m_s: float = 1e-4
    foot_swing_m_s: float = 10.0
    kinematics_m: float = 1e-3
    leg_velocity_m_s: float = 0.02

    def __post_init__(self) -> None:
        for name in ("accel_m_s2", "foot_slip_m_s", "foot_swing_m_s", "kinematics_m", "leg_velocity_m_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise EstimatorError(f"noise {name} must be finite and > 0; got {value}")


class _Terms(NamedTuple):
    """One contact pattern's filter terms (made once per pattern).

    Attributes:
        rows: The rows of ``_leg_rows`` of the feet in contact (their positions', then their velocities').
        H: The measurement matrix over the state axis by axis (3 m columns): each axis's block of
            rows (each foot's position relative to the base, then the base velocity through each
            leg), then on flat ground one row per foot in contact (its height).
        R: The measurements' noise covariance (diagonal).
        walk: The covariance's random-walk rates (zero for the base, each foot's variance rate).
        z: The measurements' buffer: the legs' rows are written each update, the ground's keep
            ``ground_z_m``.
        z_legs: ``z``'s legs' rows as (3, 2 k): an axis a row (a view).
    """

    rows: np.ndarray
    H: np.ndarray
    R: np.ndarray
    walk: np.ndarray
    z: np.ndarray
    z_legs: np.ndarray


class LegKinematicsEstimator:
    """Base position and linear velocity from leg kinematics and the IMU (see the module docstring).

    Implements :class:`~mbctl.robots.interface.BaseStateEstimator`.

    Args:
        robot: A floating-base robot (its Pinocchio model is used).
        feet: Foot frame -> its contact point p_FP (3,) [m] in that frame (e.g. the sole's centre).
        imu_site: The frame of the IMU in the model (a site).
        noise: The filter's noise models.
        start_xy_m: The base's (x, y) [m] in W at ``reset`` (W is where the robot started).
        ground_z_m: Height [m] of the ground the feet stand on at ``reset``.
        ground_noise_m: On flat ground, the standard deviation [m] of the measurement "a foot in
            contact is at ``ground_z_m``" (e.g. 0.002); None (default) for uneven ground: no such
            measurement, the height carried from foot to foot.
        max_dt_s: Longest IMU integration step [s]: after a gap in the readings (a stalled
            process, lost messages) the prediction covers at most this, and the legs correct the rest.

    Raises:
        EstimatorError: A fixed-base robot, no feet, or an unknown frame.
    """

    def __init__(
        self,
        robot: Robot,
        feet: Mapping[str, npt.ArrayLike],
        imu_site: str,
        noise: LegKinematicsNoise | None = None,
        *,
        start_xy_m: tuple[float, float] = (0.0, 0.0),
        ground_z_m: float = 0.0,
        ground_noise_m: float | None = None,
        max_dt_s: float = 0.02,
    ):
        if not robot.has_floating_base:
            raise EstimatorError(f"{robot.name} has a fixed base: there is no base state to estimate")
        if not feet:
            raise EstimatorError("give at least one foot frame with its contact point")
        self.model = robot.pin_model
        self.data = self.model.createData()
        unknown = [f for f in (*feet, imu_site) if not self.model.existFrame(f)]
        if unknown:
            raise EstimatorError(f"unknown frames {unknown}; the model has sites and bodies such as "
                                 f"{[f.name for f in self.model.frames][1:8]}")
        self.feet = tuple(feet)
        self._fids = [self.model.getFrameId(f) for f in self.feet]
        self._p_FP = [np.asarray(feet[f], dtype=float).reshape(3) for f in self.feet]
        self._p_FP_list = [p.tolist() for p in self._p_FP]
        self.noise = noise or LegKinematicsNoise()
        self.start_xy_m = (float(start_xy_m[0]), float(start_xy_m[1]))
        self.ground_z_m = float(ground_z_m)
        if ground_noise_m is not None and not (np.isfinite(ground_noise_m) and ground_noise_m > 0):
            raise EstimatorError(f"ground_noise_m must be finite and > 0 (or None); got {ground_noise_m}")
        self.ground_noise_m = None if ground_noise_m is None else float(ground_noise_m)
        self.max_dt_s = float(max_dt_s)
        self._g_W = np.array(self.model.gravity.linear)
        # the IMU's placement in the base, at the neutral joint configuration (it is on the base)
        pin.framesForwardKinematics(self.model, self.data, pin.neutral(self.model))
        X_BI = self.data.oMf[self.model.getFrameId(imu_site)]
        self._R_BI = X_BI.rotation.copy()
        self._R_IB = self._R_BI.T.copy()
        self._q_IB = pin.Quaternion(self._R_BI).inverse().coeffs().tolist()  # (x, y, z, w)
        n = len(self.feet)
        self._contact = np.ones(n, dtype=bool)
        self._q_fk = pin.neutral(self.model)
        self._v_fk = np.zeros(self.model.nv)
        m = self._m = 2 + n
        self._X_axes = np.zeros((3, m))  # a row per world axis: [p_WB, v_WB, p_WP1..n] along it
        self._X = self._X_axes.T  # (m, 3) view: rows p_WB, v_WB, p_WP1..n; a column per axis
        self._x_axes = self._X_axes.reshape(-1)  # (3 m,) view: the filter's state, axis by axis
        self._P = np.eye(3 * m)  # its covariance: block-diagonal, a block per axis
        # views of P (never rebound): p_WB's and v_WB's rows and columns on each axis, the diagonal
        by_row, by_col = self._P.reshape(3, m, 3 * m), self._P.reshape(3 * m, 3, m)
        self._P_p_rows, self._P_v_rows = by_row[:, 0], by_row[:, 1]
        self._P_p_cols, self._P_v_cols = by_col[:, :, 0], by_col[:, :, 1]
        self._P_diagonal = np.einsum("ii->i", self._P)
        # x's order (the textbook filter's: element k of p_WB, v_WB, each p_WP) from the axes' order
        self._to_x = (np.arange(3)[None, :] * m + np.arange(m)[:, None]).ravel()
        self._t: float | None = None
        self._patterns: dict[bytes, _Terms] = {}
        self._leg_rows = np.zeros((2 * n, 3))  # each leg's p_BP, then each leg's base velocity

    @property
    def estimated(self) -> tuple[str, ...]:
        """Base position and linear velocity (orientation and angular velocity are the IMU's)."""
        return (BASE_POSITION, BASE_LINEAR_VELOCITY)

    def set_contacts(self, in_contact: Mapping[str, bool]) -> None:
        """Say which feet are on the ground (all are, until told otherwise).

        Raises:
            EstimatorError: An unknown foot.
        """
        for foot, flag in in_contact.items():
            if foot not in self.feet:
                raise EstimatorError(f"unknown foot {foot!r}; the estimator's feet are {list(self.feet)}")
            self._contact[self.feet.index(foot)] = bool(flag)

    # ------------------------------------------------------------------ kinematics
    def _orientation(self, reading: Proprioception) -> tuple[np.ndarray, list[float]]:
        """R_WB and q_WB (x, y, z, w) from the IMU's quaternion: ``q_WB = q_WI q_IB`` (plain floats)."""
        w, x, y, z = np.asarray(reading.imu.quat_wxyz, dtype=float).tolist()
        bx, by, bz, bw = self._q_IB
        q_WB = [w * bx + x * bw + y * bz - z * by, w * by - x * bz + y * bw + z * bx,
                w * bz + x * by - y * bx + z * bw, w * bw - x * bx - y * by - z * bz]
        return quat_xyzw_to_matrix(q_WB), q_WB

    def _gyro_accel_B(self, reading: Proprioception) -> np.ndarray:
        """(2, 3): the gyro's w_B [rad/s] and the accelerometer's specific force f_B [m/s^2], in B."""
        return np.dot((reading.imu.gyro_I, reading.imu.accel_I), self._R_IB)  # rows: R_BI u = (u^T R_IB)^T

    def _legs(self, reading: Proprioception, w_B: list[float]) -> tuple[np.ndarray, np.ndarray]:
        """p_BP (n, 3) [m] and the base velocity each leg implies, in B (n, 3) [m/s]."""
        self._q_fk[7:] = reading.q_joints
        self._v_fk[6:] = reading.v_joints
        pin.forwardKinematics(self.model, self.data, self._q_fk, self._v_fk)
        n = len(self.feet)
        p_BP, v_B = self._leg_rows[:n], self._leg_rows[n:]  # (written in place: copies when kept)
        # on plain floats: a few 3-vectors per leg, where numpy's per-call cost was most of the work
        for i, fid in enumerate(self._fids):
            X_BF = pin.updateFramePlacement(self.model, self.data, fid)
            (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = X_BF.rotation.tolist()
            tx, ty, tz = X_BF.translation.tolist()
            fx, fy, fz = self._p_FP_list[i]
            r = (r00 * fx + r01 * fy + r02 * fz, r10 * fx + r11 * fy + r12 * fz,
                 r20 * fx + r21 * fy + r22 * fz)  # p_FP in B's axes
            p = (tx + r[0], ty + r[1], tz + r[2])  # p_BP
            vel = pin.getFrameVelocity(self.model, self.data, fid, pin.LOCAL_WORLD_ALIGNED)
            # the point's velocity relative to B, then the base's: -(v_BP + w_B x p_BP)
            (lx, ly, lz), (ax, ay, az) = vel.linear.tolist(), vel.angular.tolist()
            (cx, cy, cz), (dx, dy, dz) = cross3((ax, ay, az), r), cross3(w_B, p)
            p_BP[i] = p
            v_B[i] = (-(lx + cx + dx), -(ly + cy + dy), -(lz + cz + dz))
        return p_BP, v_B

    def _pattern(self) -> _Terms:
        """The terms of the feet in contact now, made once per contact pattern (see :class:`_Terms`)."""
        key = self._contact.tobytes()
        terms = self._patterns.get(key)
        if terms is None:
            feet = np.flatnonzero(self._contact)
            k, m, nz = len(feet), self._m, self.noise
            H = np.zeros((2 * k, m))  # one axis's rows
            H[np.arange(k), 0] = -1.0  # p_WP - p_WB
            H[np.arange(k), 2 + feet] = 1.0
            H[k + np.arange(k), 1] = 1.0  # v_WB
            r = np.concatenate([np.full(k, nz.kinematics_m**2), np.full(k, nz.leg_velocity_m_s**2)])
            grounded = feet if self.ground_noise_m is not None else feet[:0]
            H_all = np.zeros((6 * k + len(grounded), 3 * m))
            H_all[:6 * k] = np.kron(np.eye(3), H)  # each axis's block
            H_all[6 * k + np.arange(len(grounded)), 2 * m + 2 + grounded] = 1.0  # p_WP,z = ground_z_m
            ground_r = np.full(len(grounded), (self.ground_noise_m or 0.0) ** 2)
            r_all = np.diag(np.concatenate([r, r, r, ground_r]))
            rates = np.where(self._contact, nz.foot_slip_m_s, nz.foot_swing_m_s) ** 2
            walk = np.tile(np.concatenate([[0.0, 0.0], rates]), 3)
            z = np.full(len(r_all), self.ground_z_m)  # the ground's rows keep theirs
            rows = np.concatenate([feet, len(self.feet) + feet])  # the feet's rows of _leg_rows
            terms = self._patterns[key] = _Terms(rows, H_all, r_all, walk, z, z[:6 * k].reshape(3, 2 * k))
        return terms

    @property
    def x(self) -> np.ndarray:
        """The state [p_WB, v_WB, p_WP1, ..., p_WPn] (6 + 3 n,) [m, m/s] in W (a copy)."""
        return self._X.flatten()  # its rows in order: p_WB, v_WB, then the feet

    @property
    def P(self) -> np.ndarray:
        """The state's covariance (6 + 3 n, 6 + 3 n) in ``x``'s order (a copy)."""
        return self._P[np.ix_(self._to_x, self._to_x)]

    # ------------------------------------------------------------------ filter
    def reset(self, reading: Proprioception) -> None:
        """Start at rest: base (x, y) at ``start_xy_m``, the lowest contact point on the ground."""
        R_WB, _ = self._orientation(reading)
        w_B = self._gyro_accel_B(reading)[0]
        p_BP, _ = self._legs(reading, w_B.tolist())
        p_WP_rel = p_BP @ R_WB.T  # R_WB p_BP, per foot
        base = np.array([*self.start_xy_m, self.ground_z_m - p_WP_rel[:, 2].min()])
        self._X[:] = np.vstack([base, np.zeros(3), base + p_WP_rel])
        self._P[:] = np.diag(np.tile([1e-6, 1e-4] + [1e-6] * len(self.feet), 3))
        self._t = float(reading.time_s)

    def update(self, reading: Proprioception) -> tuple[np.ndarray, np.ndarray]:
        """Predict with the IMU, correct with the legs in contact; the base's q (7,) and v (6,).

        Raises:
            EstimatorError: ``update`` before ``reset``, or readings that are not finite.
        """
        if self._t is None:
            raise EstimatorError("call reset(reading) with the first reading before update()")
        R_WB, q_WB = self._orientation(reading)
        w_B, f_B = self._gyro_accel_B(reading)
        dt = min(float(reading.time_s) - self._t, self.max_dt_s)
        self._t = float(reading.time_s)
        nz = self.noise
        X = self._X
        terms = self._pattern()
        if dt > 0:
            a_W = R_WB @ f_B + self._g_W
            X[0] += X[1] * dt + 0.5 * dt * dt * a_W
            X[1] += a_W * dt
            q_diag = terms.walk * dt
            q_axes = q_diag.reshape(3, -1)
            q_axes[:, 0] = (0.5 * nz.accel_m_s2 * dt * dt) ** 2
            q_axes[:, 1] = nz.accel_m_s2**2 * dt
            # F = I + dt [[0, 1], [0, 0]] on each axis's (p, v); feet unchanged: F P F^T in place
            self._P_p_rows += dt * self._P_v_rows
            self._P_p_cols += dt * self._P_v_cols
            self._P_diagonal += q_diag
        self._legs(reading, w_B.tolist())
        if len(terms.rows):
            # the legs' rows along each axis (R_WB u for each, an axis a row), then the ground's
            np.dot(R_WB, self._leg_rows[terms.rows].T, out=terms.z_legs)
            _correct(self._x_axes, self._P, terms.H, terms.z, terms.R)
        if not all_finite(self._x_axes.tolist()):
            raise EstimatorError(f"the estimate diverged at t={reading.time_s:.3f} s (non-finite "
                                 "readings or noise models); check the IMU and encoder values")
        q_base = np.concatenate([X[0], q_WB])  # (x, y, z, w)
        v_base = np.concatenate([R_WB.T @ X[1], w_B])
        return q_base, v_base

    @property
    def foot_positions_W(self) -> dict[str, np.ndarray]:
        """The estimated contact points p_WP (3,) [m] by foot (copies)."""
        return {f: self._X[2 + i].copy() for i, f in enumerate(self.feet)}


def _correct(X: np.ndarray, P: np.ndarray, H: np.ndarray, Z: np.ndarray, R: np.ndarray) -> None:
    """The Kalman correction, in place, of the state ``X`` and its covariance ``P``.

    The measurements ``Z`` are ``H X`` plus noise of covariance ``R`` (diagonal).
    """
    PHt = P @ H.T
    S = H @ PHt
    S += R
    # K^T = S^-1 (P H^T)^T by Cholesky (S is symmetric positive definite); LAPACK directly, positionally
    # (lower, overwrite_a): numpy.linalg.solve's wrapper costs ~20 us of Python per call at this size
    _, Kt, info = dposv(S, PHt.T, 1, 1)
    if info != 0:  # (not positive definite: from non-finite readings)
        X[:] = np.nan
    X += Kt.T @ (Z - H @ X)
    P -= Kt.T @ PHt.T
    np.add(P, P.T, out=P)  # symmetric again (numpy buffers the overlapping operand)
    P *= 0.5
