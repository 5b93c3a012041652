"""Whole-body inverse dynamics for a floating-base robot on its feet (the TSID / placo class).

Formulation (one QP per control cycle; W world, F a foot frame, P a contact point)::

    x = [vdot (nv); f (3 n_p)]                 f_P: force on point P, in W [N]

    min   sum_tasks w^2 |J vdot - (a_des - Jdot v)|^2 + w_f^2 |f|^2 + w_r^2 |vdot|^2
    s.t.  M_u vdot + b_u = sum_P J_Pu^T f_P                 unactuated rows (the base)
          J_F vdot + Jdot_F v = kp S log6(X_F,F0) - kd v_F  each foot in contact (LOCAL; S: x, y, yaw)
          |f_Px|, |f_Py| <= mu/sqrt(2) f_Pz                 friction pyramid, inscribed in the cone
          w_c f_min <= f_Pz <= w_c f_max                    normal force; w_c in [0, 1] ramps
          tau_min <= M_a vdot + b_a - sum_P J_Pa^T f_P <= tau_max     torque limits
          vdot_lo(q, v) <= vdot_j <= vdot_hi(q, v)          joint limits reached in T_lim at most

tau is eliminated through the actuated rows (``tau = M_a vdot + b_a - J_a^T f``, the second
line of the dynamics split by ``S``), so the QP has nv + 3 n_p variables and the torque limits
become inequalities on x. Contact points are the corners of each sole (the Menagerie G1 stands on
four spheres per foot), so the centre of pressure stays inside the sole rectangle whenever the
normal forces are non-negative; friction comes from the foot geoms. Joint-limit bounds keep
``q + v T + vdot T^2 / 2`` inside the limits over the horizon T.

Contacts switch with force ramps: ``w_c`` goes from 1 to 0 (or back) over ``ramp_s`` while the
foot's acceleration constraint stays, so the load moves to the other foot before the foot is
released (then a swing-foot task takes over), and no torque jumps.

Solved with qpsolvers' ``daqp`` (dense dual active set), picked by benchmark
(``bench/bench_wbc.py``): on the G1's QP (59 variables, 18 equalities, 90 inequality rows and a
bound on every variable) daqp solves in ~75 us, proxqp in ~245 us (to 4e-6), osqp in ~1,300 us and
lands 3.3 away at its default tolerances. Each solve starts from the previous solution
(``WBCConfig.warm_start``); daqp then takes its initial working set from the constraints active
there. In standing and squatting no inequality is active at the solution and a cold start needs
one active-set iteration, so warm starting saves nothing measurable there (bench: 82 against 80
us); it can only pay when friction, torque or force bounds are active.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import qpsolvers

from mbctl.control.controller import JointMap
from mbctl.control.exceptions import WBCInfeasible, WBCSetupError
from mbctl.control.wbc.contacts import FootContact
from mbctl.control.wbc.tasks import AccelerationTask, DynamicsState
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


@dataclass(frozen=True)
class WBCConfig:
    """Options of the whole-body QP.

    Attributes:
        f_min_n: Minimum normal force per contact point at full weight [N] (>= 0).
        f_max_n: Maximum normal force per contact point at full weight [N] (> f_min_n).
        contact_omega_rad_s: Natural frequency of the foot-drift feedback [rad/s] (>= 0).
        force_weight: Regularisation weight on the contact forces [cost]/[N].
        acceleration_weight: Regularisation weight on vdot [cost]/[rad/s^2].
        joint_limit_horizon_s: Horizon T [s] of the joint-limit acceleration bounds (> 0).
        ramp_s: Duration [s] of a contact's force ramp (> 0).
        solver: qpsolvers backend name.
        warm_start: Start each solve from the previous cycle's solution (daqp: its nearly
            active constraints become the initial working set).
    """

    f_min_n: float = 1.0
    f_max_n: float = 400.0
    contact_omega_rad_s: float = 10.0
    force_weight: float = 1e-4
    acceleration_weight: float = 1e-3
    joint_limit_horizon_s: float = 0.1
    ramp_s: float = 0.3
    solver: str = "daqp"
    warm_start: bool = True

    def __post_init__(self) -> None:
        checks = {
            "f_min_n": self.f_min_n >= 0, "f_max_n": self.f_max_n > self.f_min_n,
            "contact_omega_rad_s": self.contact_omega_rad_s >= 0, "force_weight": self.force_weight > 0,
            "acceleration_weight": self.acceleration_weight > 0,
            "joint_limit_horizon_s": self.joint_limit_horizon_s > 0, "ramp_s": self.ramp_s > 0,
        }
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (np.isfinite(value) and ok):
                raise WBCSetupError(f"WBCConfig.{name}={value!r} is out of range")
        if self.solver not in qpsolvers.available_solvers:
            raise WBCSetupError(f"QP solver {self.solver!r} is not installed; available: "
                                f"{', '.join(sorted(qpsolvers.available_solvers))}")


@dataclass
class _ContactState:
    contact: FootContact
    fid: int
    cols: slice                       # its force variables in x
    fz: np.ndarray                    # the normal-force variables among them
    active: bool = True               # foot-acceleration equality in force
    weight: float = 1.0               # force ramp w_c in [0, 1]
    target_weight: float = 1.0
    X_WF0: pin.SE3 = field(default_factory=pin.SE3.Identity)  # where the foot was put down


@dataclass(frozen=True)
class WBCSolution:
    """What the last QP returned (world frame W).

    Attributes:
        tau: Joint torques (n_actuated,) [N m], actuator order.
        vdot: Accelerations (nv,), Pinocchio convention.
        forces_W: Contact point forces by foot name, (n_points, 3) [N] in W.
        points_W: Contact point positions by foot name, (n_points, 3) [m] in W.
        foot_origins_W: Foot frame origins by foot name, (3,) [m] in W.
        controller_time_s: Wall time of the whole ``compute`` [s].
        qp_time_s: Wall time of the QP solve alone [s].
    """

    tau: np.ndarray
    vdot: np.ndarray
    forces_W: dict[str, np.ndarray]
    points_W: dict[str, np.ndarray]
    foot_origins_W: dict[str, np.ndarray]
    controller_time_s: float
    qp_time_s: float

    @functools.cached_property
    def wrenches_W(self) -> dict[str, np.ndarray]:
        """Foot wrench about the foot frame origin, in W, [f; m] (6,) [N, N m], by foot name."""
        out = {}
        for name, F in self.forces_W.items():
            r = self.points_W[name] - self.foot_origins_W[name]
            out[name] = np.concatenate([F.sum(0), np.cross(r, F).sum(0)])
        return out

    @functools.cached_property
    def cop_W(self) -> dict[str, np.ndarray]:
        """Centre of pressure (3,) [m] in W by foot name (NaN for a foot without normal force)."""
        out = {}
        for name, F in self.forces_W.items():
            fz = F[:, 2].sum()
            out[name] = (F[:, 2] @ self.points_W[name]) / fz if fz > 1e-6 else np.full(3, np.nan)
        return out


#: ``r @ _SKEW`` is ``[r]x`` flattened row-major, for every row r: stacked cross-product matrices.
_SKEW = np.array([[0, 0, 0, 0, 0, -1, 0, 1, 0], [0, 0, 1, 0, 0, 0, -1, 0, 0], [0, -1, 0, 1, 0, 0, 0, 0, 0]],
                 dtype=float)


def _as_slice(idx: np.ndarray) -> slice | np.ndarray:
    """``idx`` as a slice when it is a contiguous increasing run (indexing then gives views)."""
    if len(idx) and np.array_equal(idx, np.arange(idx[0], idx[0] + len(idx))):
        return slice(int(idx[0]), int(idx[0]) + len(idx))
    return idx


class WholeBodyController:
    """Whole-body inverse dynamics on a Pinocchio model; torque commands for every actuated joint.

    Example::

        ctrl = WholeBodyController(robot, feet=[left, right])
        ctrl.add_task(ComAcceleration(TaskGains(10.0, omega_rad_s=8.0)))
        ...
        command = ctrl.compute(state)          # RobotState in, torque Command out
        ctrl.last.forces_W["left_foot"]        # predicted contact forces [N]

    Args:
        robot: The robot (actuators name the torque outputs; tau limits from their force ranges).
        feet: Foot contacts (see :func:`~mbctl.control.wbc.contacts.foot_contact_from_model`).
        config: QP options.
        pin_model: The controller's analytic model (default ``robot.pin_model``; pass a perturbed
            copy to study model error; same nq and nv).

    Raises:
        WBCSetupError: A model of another size, duplicate foot names, or unknown frames.
    """

    def __init__(self, robot: Robot, feet: Sequence[FootContact], config: WBCConfig | None = None,
                 pin_model: pin.Model | None = None):
        self._config = config or WBCConfig()
        self.model = pin_model if pin_model is not None else robot.pin_model
        if (self.model.nq, self.model.nv) != (robot.pin_model.nq, robot.pin_model.nv):
            raise WBCSetupError(f"pin_model has nq={self.model.nq}, nv={self.model.nv}; the robot has "
                                f"nq={robot.pin_model.nq}, nv={robot.pin_model.nv}")
        self.state = DynamicsState(self.model)
        self.joints = JointMap.from_robot(robot)
        nv = self.model.nv
        self._act = np.asarray(self.joints.idx_v, dtype=int)
        self._unact = np.setdiff1d(np.arange(nv), self._act)
        self._n_unact = len(self._unact)
        self._a, self._u = _as_slice(self._act), _as_slice(self._unact)  # views where contiguous
        self.tau_low = np.array(self.joints.tau_low, dtype=float)
        self.tau_high = np.array(self.joints.tau_high, dtype=float)
        self._command_names = self.joints.command_names
        self.contacts: dict[str, _ContactState] = {}
        col = nv
        for foot in feet:
            if foot.name in self.contacts:
                raise WBCSetupError(f"duplicate foot name {foot.name!r}")
            if not self.model.existFrame(foot.frame):
                raise WBCSetupError(f"unknown foot frame {foot.frame!r}")
            cols = slice(col, col + 3 * foot.n_points)
            self.contacts[foot.name] = _ContactState(foot, self.model.getFrameId(foot.frame), cols,
                                                     np.arange(cols.start + 2, cols.stop, 3))
            col = cols.stop
        self.n_x = col
        self.config = self._config  # the setter derives the regularisation diagonal
        n_f = col - nv
        self._n_fric = 4 * n_f // 3
        self._G = np.zeros((self._n_fric + 2 * len(self._act), col))
        self._h = np.zeros(self._G.shape[0])
        self._lb = np.full(col, -np.inf)
        self._ub = np.full(col, np.inf)
        row = 0
        for cs in self.contacts.values():  # friction pyramid rows: |f_x|, |f_y| <= mu / sqrt(2) f_z
            mu = cs.contact.mu / np.sqrt(2.0)
            for c0 in range(cs.cols.start, cs.cols.stop, 3):
                for axis in (0, 1):
                    for sign in (1.0, -1.0):
                        self._G[row, c0 + axis] = sign
                        self._G[row, c0 + 2] = -mu
                        row += 1
        self.tasks: list[AccelerationTask] = []
        self._limits = self._joint_limits()
        self.last: WBCSolution | None = None
        self._x_warm: np.ndarray | None = None
        self.steps = 0

    @property
    def config(self) -> WBCConfig:
        """QP options (assignable)."""
        return self._config

    @config.setter
    def config(self, config: WBCConfig) -> None:
        self._config = config
        nv = self.model.nv
        self._regularisation = np.concatenate([np.full(nv, config.acceleration_weight**2),
                                               np.full(self.n_x - nv, config.force_weight**2)])

    @property
    def solution(self) -> WBCSolution:
        """The last QP's solution.

        Raises:
            WBCSetupError: ``compute`` has not run yet.
        """
        if self.last is None:
            raise WBCSetupError("no solution yet: call compute(state) first")
        return self.last

    # ------------------------------------------------------------------ setup
    def _joint_limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(v index, q index, q_min, q_max) of actuated 1-dof joints with finite limits."""
        iv, iq, lo, hi = [], [], [], []
        for j in range(1, self.model.njoints):
            joint = self.model.joints[j]
            if joint.nv != 1 or joint.nq != 1 or joint.idx_v not in self._act:
                continue
            q_lo = self.model.lowerPositionLimit[joint.idx_q]
            q_hi = self.model.upperPositionLimit[joint.idx_q]
            if np.isfinite(q_lo) and np.isfinite(q_hi) and q_hi > q_lo:
                iv.append(joint.idx_v)
                iq.append(joint.idx_q)
                lo.append(q_lo)
                hi.append(q_hi)
        return np.array(iv, dtype=int), np.array(iq, dtype=int), np.array(lo), np.array(hi)

    def add_task(self, task: AccelerationTask) -> AccelerationTask:
        """Add a task (kept until ``remove_task``); returns it."""
        self.tasks.append(task)
        return task

    def remove_task(self, task: AccelerationTask) -> None:
        """Remove a task (no-op if absent)."""
        if task in self.tasks:
            self.tasks.remove(task)

    def reset_contacts(self, state: RobotState) -> None:
        """Every foot in contact at full weight, held where it is at ``state``."""
        self.state.update(state.q, state.v)
        for c in self.contacts.values():
            c.active, c.weight, c.target_weight = True, 1.0, 1.0
            c.X_WF0 = pin.SE3(self.state.frame_pose(c.fid))

    def release(self, foot: str) -> None:
        """Ramp ``foot``'s force down to zero; the foot stays constrained until then."""
        self._contact(foot).target_weight = 0.0

    def touch_down(self, foot: str) -> None:
        """Constrain ``foot`` where it is now and ramp its force up from zero."""
        c = self._contact(foot)
        c.active, c.target_weight = True, 1.0
        c.weight = min(c.weight, 0.0)
        c.X_WF0 = pin.SE3(self.state.frame_pose(c.fid))

    def contact_released(self, foot: str) -> bool:
        """Whether ``foot`` is free (its ramp ended and its constraint was removed)."""
        return not self._contact(foot).active

    def _contact(self, foot: str) -> _ContactState:
        if foot not in self.contacts:
            raise WBCSetupError(f"unknown foot {foot!r}; feet: {', '.join(self.contacts)}")
        return self.contacts[foot]

    # ------------------------------------------------------------------ per cycle
    def _advance_ramps(self, dt_s: float) -> None:
        step = dt_s / self.config.ramp_s
        for c in self.contacts.values():
            if c.weight < c.target_weight:
                c.weight = min(c.target_weight, c.weight + step)
            elif c.weight > c.target_weight:
                c.weight = max(c.target_weight, c.weight - step)
            if c.target_weight == 0.0 and c.weight == 0.0:
                c.active = False

    def compute(self, state: RobotState, reference: object = None, dt_s: float = 0.0) -> Command:
        """Torques for ``state`` (the current task references); ramps advance by ``dt_s`` [s].

        Raises:
            WBCInfeasible: The QP has no solution (carries the problem and the solver result).
        """
        t0 = time.perf_counter()
        self._advance_ramps(dt_s)
        s = self.state
        s.update(state.q, state.v)
        nv, n_x = self.model.nv, self.n_x
        cfg = self.config
        # tasks: one stacked weighted least-squares block, H = Jw^T Jw, c = -Jw^T rw
        J_rows, r_rows = [], []
        for task in self.tasks:
            J, r = task.rows(s)
            J_rows.append(task.gains.weight * J)
            r_rows.append(task.gains.weight * r)
        H = np.zeros((n_x, n_x))
        c = np.zeros(n_x)
        if J_rows:
            Jw = np.vstack(J_rows)
            H[:nv, :nv] = Jw.T @ Jw
            c[:nv] = -(Jw.T @ np.concatenate(r_rows))
        np.einsum("ii->i", H)[:] += self._regularisation  # a writable view of the diagonal

        # contact Jacobians of the points, in W: J_P = J_lin - [p_WP - p_WF]x J_ang
        Jc = np.zeros((n_x - nv, nv))
        eq_rows: list[np.ndarray] = []
        eq_rhs: list[np.ndarray] = []
        lb, ub = self._lb, self._ub
        G, h = self._G, self._h  # friction rows are constant (built once); torque rows below
        row = self._n_fric
        kp_c = cfg.contact_omega_rad_s**2
        kd_c = 2.0 * cfg.contact_omega_rad_s
        points_W, origins_W = {}, {}
        for name, cs in self.contacts.items():
            X_WF = s.frame_pose(cs.fid)
            R_WF = X_WF.rotation
            J_lwa = s.frame_jacobian(cs.fid, pin.LOCAL_WORLD_ALIGNED)
            J_lin, J_ang = J_lwa[:3], J_lwa[3:]
            r_W = cs.contact.points_F @ R_WF.T  # (n, 3)
            origins_W[name] = X_WF.translation.copy()
            points_W[name] = r_W + origins_W[name]
            block = Jc[cs.cols.start - nv:cs.cols.stop - nv].reshape(-1, 3, nv)
            block[:] = J_lin - ((r_W @ _SKEW).reshape(-1, 3) @ J_ang).reshape(-1, 3, nv)
            lb[cs.fz] = cs.weight * cfg.f_min_n
            ub[cs.fz] = cs.weight * cfg.f_max_n
            if cs.active:
                eq = np.zeros((6, n_x))
                eq[:3, :nv] = R_WF.T @ J_lin  # J_F in LOCAL: the same twist in F's axes
                eq[3:, :nv] = R_WF.T @ J_ang
                drift = s.frame_drift(cs.fid, pin.LOCAL)
                err = pin.log6(X_WF.actInv(cs.X_WF0)).vector
                err[2:5] = 0.0  # the ground sets height, roll and pitch; feedback corrects slip only
                a_fb = kp_c * err - kd_c * (eq[:, :nv] @ s.v)
                eq_rows.append(eq)
                eq_rhs.append(a_fb - drift)
        M, b = s.M, s.b
        u, a = self._u, self._a
        dyn = np.zeros((self._n_unact, n_x))
        dyn[:, :nv] = M[u]
        dyn[:, nv:] = -Jc[:, u].T
        A_eq = np.vstack([dyn, *eq_rows])
        b_eq = np.concatenate([-b[u], *eq_rhs])
        # torque rows: tau = T x + b_a with T = [M_a, -Jc_a^T]; tau_min <= tau <= tau_max
        n_a = len(self.tau_low)
        T = G[row:row + n_a]
        T[:, :nv] = M[a]
        T[:, nv:] = -Jc[:, a].T
        np.negative(T, out=G[row + n_a:row + 2 * n_a])
        b_a = b[a]
        h[row:row + n_a] = self.tau_high - b_a
        h[row + n_a:row + 2 * n_a] = b_a - self.tau_low
        # joint limits: q + v T + vdot T^2/2 within [q_min, q_max]
        iv, iq, q_lo, q_hi = self._limits
        if len(iv):
            Th = cfg.joint_limit_horizon_s
            q, v = s.q[iq], s.v[iv]
            lo = 2.0 * (q_lo - q - v * Th) / Th**2
            hi = 2.0 * (q_hi - q - v * Th) / Th**2
            lb[iv] = np.minimum(lo, 0.0)
            ub[iv] = np.maximum(hi, 0.0)
        problem = qpsolvers.Problem(H, c, G, h, A_eq, b_eq, lb, ub)
        t_qp = time.perf_counter()
        initvals = self._x_warm if cfg.warm_start else None
        result = qpsolvers.solve_problem(problem, solver=cfg.solver, initvals=initvals)
        qp_time = time.perf_counter() - t_qp
        if not result.found or result.x is None or not np.isfinite(result.x).all():
            raise WBCInfeasible(
                f"whole-body QP infeasible at step {self.steps} (solver {cfg.solver}): contacts "
                + ", ".join(f"{n} weight {cs.weight:.2f}" for n, cs in self.contacts.items())
                + f"; normal force per point {cfg.f_min_n:g} to {cfg.f_max_n:g} N at full weight; "
                f"torque limits [{self.tau_low.min():.1f}, {self.tau_high.max():.1f}] N m. Check the "
                "force bounds and torque limits against the load, the friction and the task targets.",
                qpsolvers.Problem(H, c, G.copy(), h.copy(), A_eq, b_eq, lb.copy(), ub.copy()), result,
                cfg.solver)
        x = result.x
        self._x_warm = x
        vdot, f = x[:nv], x[nv:]
        tau = T @ x + b_a
        np.maximum(tau, self.tau_low, out=tau)  # np.clip costs twice as much at this size
        np.minimum(tau, self.tau_high, out=tau)
        self.steps += 1
        forces_W = {name: f[cs.cols.start - nv:cs.cols.stop - nv].reshape(-1, 3)
                    for name, cs in self.contacts.items()}
        self.last = WBCSolution(tau, vdot, forces_W, points_W, origins_W, time.perf_counter() - t0, qp_time)
        return Command(CommandKind.TORQUE, tau, self._command_names)
