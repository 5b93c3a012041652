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
through the measurements. It is also the same along each world axis: the prediction, the
measurement rows and every noise act on x, y and z alike, with no cross-axis terms, and the
covariance starts isotropic, so it stays the Kronecker product of one (2 + n) x (2 + n)
covariance over [p, v, p_P1, ..., p_Pn] with the 3 x 3 identity. The filter keeps that one
covariance and the state as a (2 + n) x 3 matrix (one column per axis): one gain serves all three
axes, the same estimate as the full (6 + 3 n) filter (``P`` gives its covariance; the two agree to
7e-13 over a humanoid's walk) on matrices a ninth of the size (69 against 75 us an update on a
29-joint humanoid, replayed; numpy's per-call cost dominates at either size). The orientation and
the legs' kinematics on plain floats took an update to 49.5 us (warm, e.g. the G1's readings
replayed).

Position and yaw are unobservable: they stay where they started and drift only as much as the
feet slip. The height is observable through the starting assumption that the contact points
are on the ground (z = ``ground_z_m``); a foot that lands takes its height from the base's, so
each step can carry an error of the height on (a sole that rolls about its edge moves the point
assumed still). On flat ground, ``ground_noise_m`` adds a measurement: each foot in contact is at
``ground_z_m``, with that standard deviation. Its rows act on z alone, so z then has a covariance
of its own (x and y share the other); without it (uneven ground) the three share one. The
second correction costs its time: 48-49 against 74-75 us an update (e.g. the G1 standing, replayed).

Out of scope: the IMU's lever arm (its centripetal acceleration, below 0.01 m/s^2 for a standing
robot), accelerometer bias, contact detection (the feet in contact are given: ``set_contacts``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

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
        self._X = np.zeros((2 + n, 3))  # rows p_WB, v_WB, p_WP1..n; a column per world axis
        self._P = np.eye(2 + n)  # the covariance of each column (the same for the three)
        self._Pz: np.ndarray | None = None  # z's own, with the ground measurement (ground_noise_m)
        self._ground_patterns: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        self._t: float | None = None
        self._patterns: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
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

    def _pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The terms of the feet in contact now (one axis), made once per contact pattern.

        Returns:
            The rows of the feet in contact (their positions', then their velocities' in the legs'
            rows), the measurement matrix of one axis (their positions
            relative to the base, then the base velocity through each), its noise variances, and
            the covariance's random-walk rates (zero for the base, each foot's variance rate).
        """
        key = self._contact.tobytes()
        terms = self._patterns.get(key)
        if terms is None:
            feet = np.flatnonzero(self._contact)
            k, m, nz = len(feet), len(self.feet) + 2, self.noise
            H = np.zeros((2 * k, m))
            H[np.arange(k), 0] = -1.0  # p_WP - p_WB
            H[np.arange(k), 2 + feet] = 1.0
            H[k + np.arange(k), 1] = 1.0  # v_WB
            r = np.concatenate([np.full(k, nz.kinematics_m**2), np.full(k, nz.leg_velocity_m_s**2)])
            rates = np.where(self._contact, nz.foot_slip_m_s, nz.foot_swing_m_s) ** 2
            walk = np.concatenate([[0.0, 0.0], rates])
            rows = np.concatenate([feet, len(self.feet) + feet])  # the feet's rows of _leg_rows
            terms = self._patterns[key] = (rows, H, r, walk)
        return terms

    @property
    def x(self) -> np.ndarray:
        """The state [p_WB, v_WB, p_WP1, ..., p_WPn] (6 + 3 n,) [m, m/s] in W (a copy)."""
        return self._X.flatten()  # its rows in order: p_WB, v_WB, then the feet

    def _ground_pattern(self, H: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The height's measurements: the legs' rows, then each foot in contact at the ground.

        Returns:
            Their matrix and noise variances (made once per contact pattern).
        """
        key = self._contact.tobytes()
        terms = self._ground_patterns.get(key)
        if terms is None:
            feet = np.flatnonzero(self._contact)
            G = np.zeros((len(feet), H.shape[1]))
            G[np.arange(len(feet)), 2 + feet] = 1.0
            noise = np.full(len(feet), self.ground_noise_m**2)  # type: ignore[operator]
            terms = self._ground_patterns[key] = (np.vstack([H, G]), np.concatenate([r, noise]))
        return terms

    @property
    def P(self) -> np.ndarray:
        """The state's covariance (6 + 3 n, 6 + 3 n) in ``x``'s order.

        The axis covariance times I_3; with the ground measurement, x and y's times diag(1, 1, 0)
        plus z's times diag(0, 0, 1).
        """
        if self._Pz is None:
            return np.kron(self._P, np.eye(3))
        return np.kron(self._P, np.diag([1.0, 1.0, 0.0])) + np.kron(self._Pz, np.diag([0.0, 0.0, 1.0]))

    # ------------------------------------------------------------------ filter
    def reset(self, reading: Proprioception) -> None:
        """Start at rest: base (x, y) at ``start_xy_m``, the lowest contact point on the ground."""
        R_WB, _ = self._orientation(reading)
        w_B = self._gyro_accel_B(reading)[0]
        p_BP, _ = self._legs(reading, w_B.tolist())
        p_WP_rel = p_BP @ R_WB.T  # R_WB p_BP, per foot
        base = np.array([*self.start_xy_m, self.ground_z_m - p_WP_rel[:, 2].min()])
        self._X = np.vstack([base, np.zeros(3), base + p_WP_rel])
        self._P = np.diag([1e-6, 1e-4] + [1e-6] * len(self.feet))
        self._Pz = None if self.ground_noise_m is None else self._P.copy()
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
        X, P, Pz = self._X, self._P, self._Pz
        rows, H, r_diag, walk = self._pattern()
        if dt > 0:
            a_W = R_WB @ f_B + self._g_W
            X[0] += X[1] * dt + 0.5 * dt * dt * a_W
            X[1] += a_W * dt
            q_diag = walk * dt
            q_diag[0] = (0.5 * nz.accel_m_s2 * dt * dt) ** 2
            q_diag[1] = nz.accel_m_s2**2 * dt
            for cov in (P,) if Pz is None else (P, Pz):
                # F = I + dt [[0, 1], [0, 0]] on (p, v); feet unchanged
                cov[0, :] += dt * cov[1, :]
                cov[:, 0] += dt * cov[:, 1]
                cov.flat[::len(cov) + 1] += q_diag
        self._legs(reading, w_B.tolist())
        if len(rows):
            # each axis's measurements: rows (positions, then velocities) x columns (x, y, z)
            Z = np.dot(self._leg_rows[rows], R_WB.T)
            if Pz is None:
                _correct(X, P, H, Z, r_diag)
            else:  # x and y as above; z with the feet at the ground too
                _correct(X[:, :2], P, H, Z[:, :2], r_diag)
                Hz, rz = self._ground_pattern(H, r_diag)
                ground = np.full((len(rz) - len(r_diag), 1), self.ground_z_m)
                _correct(X[:, 2:], Pz, Hz, np.vstack([Z[:, 2:], ground]), rz)
        if not all_finite(X.ravel().tolist()):
            raise EstimatorError(f"the estimate diverged at t={reading.time_s:.3f} s (non-finite "
                                 "readings or noise models); check the IMU and encoder values")
        q_base = np.concatenate([X[0], q_WB])  # (x, y, z, w)
        v_base = np.concatenate([R_WB.T @ X[1], w_B])
        return q_base, v_base

    @property
    def foot_positions_W(self) -> dict[str, np.ndarray]:
        """The estimated contact points p_WP (3,) [m] by foot (copies)."""
        return {f: self._X[2 + i].copy() for i, f in enumerate(self.feet)}


def _correct(X: np.ndarray, P: np.ndarray, H: np.ndarray, Z: np.ndarray, r_diag: np.ndarray) -> None:
    """The Kalman correction, in place, of the state's columns ``X`` and their covariance ``P``.

    ``X`` has a column per axis (sharing ``P``); the measurements ``Z`` (a row per measurement, a
    column per axis) are ``H X`` plus noise of variances ``r_diag``.
    """
    PHt = P @ H.T
    S = H @ PHt
    S.flat[::len(S) + 1] += r_diag
    # K^T = S^-1 (P H^T)^T by Cholesky (S is symmetric positive definite); LAPACK directly:
    # numpy.linalg.solve's wrapper costs ~20 us of Python per call at this size
    _, Kt, info = dposv(S, PHt.T, lower=1)
    if info != 0:  # (not positive definite: from non-finite readings)
        X[:] = np.nan
    X += Kt.T @ (Z - H @ X)
    P -= Kt.T @ PHt.T
    P[:] = 0.5 * (P + P.T)
