"""Whole-body inverse dynamics for a floating-base robot on its feet (the TSID / placo class).

Formulation (one QP per control cycle; W world, F a foot frame, P a contact point)::

    x = [vdot (nv); f (3 n_p)]                 f_P: force on point P, in W [N]

    min   sum_tasks |W_t vdot - r_t|^2 + w_f^2 |f|^2 + w_r^2 |vdot|^2
    s.t.  M_u vdot + b_u = sum_P J_Pu^T f_P                 unactuated rows (the base)
          J_F vdot + Jdot_F v = kp S log6(X_F,F0) - kd v_F  each foot in contact (LOCAL; S: x, y, yaw)
          |f_Px|, |f_Py| <= mu/sqrt(2) f_Pz                 friction pyramid, inscribed in the cone
          w_c f_min <= f_Pz <= w_c f_max                    normal force; w_c in [0, 1] ramps
          tau_min <= M_a vdot + b_a - sum_P J_Pa^T f_P <= tau_max     torque limits
          vdot_lo(q, v) <= vdot_j <= vdot_hi(q, v)          joint limits reached in T_lim at most

The task rows ``W_t``, ``r_t`` are the acceleration level of the task layer
(:mod:`mbctl.control.tasks`: ``W_t = diag(cost) J``, ``r_t = diag(cost) (a_des - Jdot v)``),
assembled by its ``TaskStack`` as in differential IK. tau is eliminated through the actuated rows
(``tau = M_a vdot + b_a - J_a^T f``, the second line of the dynamics split by ``S``), so the QP
has nv + 3 n_p variables and the torque limits become inequalities on x. Contact points are the
corners of each sole (e.g. the four spheres per foot the Menagerie G1 stands on), so the centre of
pressure stays inside the sole rectangle whenever the normal forces are non-negative; friction
comes from the foot geoms. Joint-limit bounds keep ``q + v T + vdot T^2 / 2`` inside the limits
over the horizon T.

Contacts switch with force ramps (:mod:`mbctl.control.wbc.contacts`): ``w_c`` goes from 1 to 0
(or back) over ``ramp_s`` of the state's time while the foot's acceleration constraint stays, so
the load moves to the other foot before the foot is released, and no torque jumps.

Solved with qpsolvers' ``daqp`` (dense dual active set), picked by benchmark
(``bench/bench_wbc.py``), e.g. on the G1's QP (59 variables, 18 equalities, 90 inequality rows, a
bound on every variable) daqp solves in ~75 us, proxqp in ~245 us (to 4e-6), osqp in ~1,300 us and
lands 3.3 away at its default tolerances. Each solve starts from the previous solution
(``WBCConfig.warm_start``); in standing and squatting no inequality is active at the solution
and warm starting saves nothing measurable there; it can only pay when bounds are active.

When the QP has no solution, ``WBCConfig.on_infeasible`` decides: raise
:class:`~mbctl.control.exceptions.WBCInfeasible`, or ("damp") switch for good to joint damping
``tau = -kd v`` and record when, so a simulation goes on and shows whether the robot falls.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
import qpsolvers

from mbctl.control.controller import JointMap
from mbctl.control.exceptions import WBCInfeasible, WBCSetupError
from mbctl.control.tasks.base import Task
from mbctl.control.tasks.stack import TaskStack
from mbctl.control.tasks.state import DynamicsState
from mbctl.control.wbc.config import WBCConfig, WBCSolution
from mbctl.control.wbc.contacts import ContactState, FootContact
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.indexing import as_slice
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot

#: ``r @ _SKEW`` is ``[r]x`` flattened row-major, for every row r: stacked cross-product matrices.
_SKEW = np.array([[0, 0, 0, 0, 0, -1, 0, 1, 0], [0, 0, 1, 0, 0, 0, -1, 0, 0], [0, -1, 0, 1, 0, 0, 0, 0, 0]],
                 dtype=float)


class WholeBodyController:
    """Whole-body inverse dynamics on a Pinocchio model; torque commands for every actuated joint.

    A :class:`~mbctl.control.controller.Controller`: ``compute(state, reference)`` takes the
    robot's state (the task targets are set on the tasks; ``reference`` is ignored) and returns a
    torque command; contact ramps advance with the state's time.

    Example::

        ctrl = WholeBodyController(robot, feet=[left, right])
        com = ctrl.add_task(ComTask(cost=10.0, servo=AccelerationGains(8.0)))
        com.set_target(p, v, a)
        command = ctrl.compute(state)          # RobotState in, torque Command out
        ctrl.solution.forces_W["l_sole"]       # predicted contact forces [N]

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
        self._a, self._u = as_slice(self._act), as_slice(self._unact)  # views where contiguous
        self.tau_low = np.array(self.joints.tau_low, dtype=float)
        self.tau_high = np.array(self.joints.tau_high, dtype=float)
        self._command_names = self.joints.command_names
        self.contacts: dict[str, ContactState] = {}
        col = nv
        for foot in feet:
            if foot.name in self.contacts:
                raise WBCSetupError(f"duplicate foot name {foot.name!r}")
            if not self.model.existFrame(foot.frame):
                raise WBCSetupError(f"unknown foot frame {foot.frame!r}")
            cols = slice(col, col + 3 * foot.n_points)
            self.contacts[foot.name] = ContactState(foot, self.model.getFrameId(foot.frame), cols,
                                                    np.arange(cols.start + 2, cols.stop, 3))
            col = cols.stop
        self.n_x = col
        self.config = self._config  # the setter derives the regularisation diagonal
        self._n_fric = 4 * (col - nv) // 3
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
        self._stack = TaskStack(nv)
        self._H = np.zeros((col, col))
        self._c = np.zeros(col)
        self._limits = self._joint_limits()
        self.last: WBCSolution | None = None
        self._x_warm: np.ndarray | None = None
        self._last_time_s: float | None = None
        self.steps = 0
        self.infeasible_at_s: float | None = None
        self.infeasible_message: str | None = None

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
    def tasks(self) -> tuple[Task, ...]:
        """The tasks in the objective, in the order they were added."""
        return self._stack.tasks

    @property
    def solution(self) -> WBCSolution:
        """The last cycle's solution.

        Raises:
            WBCSetupError: ``compute`` has not run yet.
        """
        if self.last is None:
            raise WBCSetupError("no solution yet: call compute(state) first")
        return self.last

    @property
    def fell_back(self) -> bool:
        """Whether the controller has switched to its damping fallback (``on_infeasible="damp"``)."""
        return self.infeasible_at_s is not None

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

    def add_task(self, task: Task) -> Task:
        """Add a task (kept until ``remove_task``); returns it.

        Raises:
            TaskSetupError: The task has no acceleration-level form (found at the next compute).
        """
        if task not in self._stack.tasks:
            self._stack.set_tasks([*self._stack.tasks, task])
        return task

    def remove_task(self, task: Task) -> None:
        """Remove a task (no-op if absent)."""
        if task in self._stack.tasks:
            self._stack.set_tasks([t for t in self._stack.tasks if t is not task])

    def reset(self) -> None:
        """Forget the warm start, the ramp clock and the fallback (the tasks and contacts stay)."""
        self._x_warm = None
        self._last_time_s = None
        self.infeasible_at_s = None
        self.infeasible_message = None
        self.steps = 0

    def reset_contacts(self, state: RobotState) -> None:
        """Every foot in contact at full weight, held where it is at ``state``."""
        self.state.update(state.q, state.v)
        for contact in self.contacts.values():
            contact.hold(pin.SE3(self.state.frame_pose(contact.fid)))

    def release(self, foot: str) -> None:
        """Ramp ``foot``'s force down to zero; the foot stays constrained until then."""
        self._contact(foot).target_weight = 0.0

    def touch_down(self, foot: str) -> None:
        """Constrain ``foot`` where it is now and ramp its force up from zero."""
        c = self._contact(foot)
        c.touch_down(pin.SE3(self.state.frame_pose(c.fid)))

    def contact_released(self, foot: str) -> bool:
        """Whether ``foot`` is free (its ramp ended and its constraint was removed)."""
        return not self._contact(foot).active

    def _contact(self, foot: str) -> ContactState:
        if foot not in self.contacts:
            raise WBCSetupError(f"unknown foot {foot!r}; feet: {', '.join(self.contacts)}")
        return self.contacts[foot]

    # ------------------------------------------------------------------ per cycle
    def compute(self, state: RobotState, reference: object = None) -> Command:
        """Torques for ``state`` at the tasks' current targets; ramps advance with ``state.time_s``.

        Args:
            state: Measured state, Pinocchio convention.
            reference: Unused (the targets live on the tasks); accepted for the Controller protocol.

        Raises:
            WBCInfeasible: The QP has no solution and ``on_infeasible`` is "raise" (carries the
                problem and the solver result).
        """
        t0 = time.perf_counter()
        dt_s = 0.0 if self._last_time_s is None else max(0.0, state.time_s - self._last_time_s)
        self._last_time_s = state.time_s
        for contact in self.contacts.values():
            contact.advance_ramp(dt_s, self._config.ramp_s)
        s = self.state
        s.update(state.q, state.v)
        if self.infeasible_at_s is not None:
            return self._fallback(state, t0)
        nv, n_x = self.model.nv, self.n_x
        cfg = self.config
        H, c = self._H, self._c
        H.fill(0.0)
        c.fill(0.0)
        self._stack.acceleration_objective(s, H[:nv, :nv], c[:nv])
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
            message = (
                f"whole-body QP infeasible at step {self.steps} (solver {cfg.solver}): contacts "
                + ", ".join(f"{n} weight {cs.weight:.2f}" for n, cs in self.contacts.items())
                + f"; normal force per point {cfg.f_min_n:g} to {cfg.f_max_n:g} N at full weight; "
                f"torque limits [{self.tau_low.min():.1f}, {self.tau_high.max():.1f}] N m. Check the "
                "force bounds and torque limits against the load, the friction and the task targets.")
            if cfg.on_infeasible == "raise":
                raise WBCInfeasible(
                    message, qpsolvers.Problem(H.copy(), c.copy(), G.copy(), h.copy(), A_eq, b_eq,
                                               lb.copy(), ub.copy()), result, cfg.solver, state.time_s)
            self.infeasible_at_s, self.infeasible_message = state.time_s, message
            return self._fallback(state, t0)
        x = result.x
        self._x_warm = x
        vdot, f = x[:nv], x[nv:]
        tau = T @ x + b_a
        self.steps += 1
        forces_W = {name: f[cs.cols.start - nv:cs.cols.stop - nv].reshape(-1, 3)
                    for name, cs in self.contacts.items()}
        self.last = WBCSolution(tau, vdot, forces_W, points_W, origins_W, time.perf_counter() - t0, qp_time)
        return Command(CommandKind.TORQUE, tau, self._command_names)

    def _fallback(self, state: RobotState, t0: float) -> Command:
        """Joint damping ``tau = -kd v`` within the torque limits (the ``on_infeasible="damp"`` fallback)."""
        tau = -self._config.fallback_kd_n_m_s_rad * np.asarray(state.v)[self._a]
        np.maximum(tau, self.tau_low, out=tau)
        np.minimum(tau, self.tau_high, out=tau)
        s = self.state
        points_W, origins_W, forces_W = {}, {}, {}
        for name, cs in self.contacts.items():
            X_WF = s.frame_pose(cs.fid)
            origins_W[name] = X_WF.translation.copy()
            points_W[name] = cs.contact.points_F @ X_WF.rotation.T + origins_W[name]
            forces_W[name] = np.zeros((cs.contact.n_points, 3))
        self.steps += 1
        self.last = WBCSolution(tau, np.full(self.model.nv, np.nan), forces_W, points_W, origins_W,
                                time.perf_counter() - t0, 0.0, fallback=True)
        return Command(CommandKind.TORQUE, tau, self._command_names)
