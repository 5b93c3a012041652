"""Whole-body inverse dynamics for a floating-base robot on its feet (the TSID / placo class).

Formulation (one QP per control cycle; W world, F a foot frame, P a contact point)::

    x = [vdot (nv); f (3 n_p)]                 f_P: force on point P, in its foot's frame F [N]

    min   sum_tasks |W_t vdot - r_t|^2 + w_f^2 |f|^2 + w_r^2 |vdot|^2
    s.t.  M_u vdot + b_u = sum_P J_Pu^T f_P                 unactuated rows (the base)
          J_F vdot + Jdot_F v = kp S log6(X_F,F0) - kd v_F  each foot in contact (LOCAL; S: x, y, yaw)
          |f_Px|, |f_Py| <= mu/sqrt(2) f_Pz                 friction pyramid about F's z (the sole's normal)
          |sum_P (p - c)_x f_Py - (p - c)_y f_Px| <= k sum_P f_Pz   each sole's yaw moment (torsion_m k)
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

Solved in its structure (:mod:`mbctl.control.wbc.qp`): the optimum under the equalities alone
(a KKT solve through the Schur complement, exploiting the block-diagonal Hessian), accepted when it
satisfies every inequality (always while standing or squatting: none is active), else daqp (dense
dual active set, called directly) on the whole problem. daqp was picked by benchmark
(``bench/bench_wbc.py``): e.g. on the G1's QP (59 variables, 18 equalities, 90 inequality rows, a
bound on every variable) proxqp took ~3x and osqp ~17x as long, and osqp stopped far from the
optimum at its default tolerances; ``WBCConfig.solver`` runs those through qpsolvers.

With ``WBCConfig.friction_feedforward`` the model's joint friction (Pinocchio's ``friction`` and
``damping``: the MJCF's ``frictionloss`` and ``damping``) is added to the QP's torques at the
velocity the cycle plans, ``v + vdot dt`` (a smooth sign for the Coulomb part), then clamped to the
torque limits: an unloaded limb whose torques are below its dry friction follows its task instead
of sticking.

When the QP has no solution, it is solved again without the joint-limit bounds
(``WBCConfig.relax_joint_limits``, counted in ``relaxed_cycles``); when that has none either,
``WBCConfig.on_infeasible`` decides: raise
:class:`~mbctl.control.exceptions.WBCInfeasible`, or ("damp") switch for good to joint damping
``tau = -kd v`` and record when, so a simulation goes on and shows whether the robot falls.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from scipy.linalg.blas import dgemv

from mbctl.control.controller import JointMap
from mbctl.control.exceptions import WBCInfeasible, WBCSetupError
from mbctl.control.qp import QPResult, infeasible_error
from mbctl.control.tasks.base import Task
from mbctl.control.tasks.stack import TaskStack
from mbctl.control.tasks.state import DynamicsState
from mbctl.control.wbc.config import WBCConfig, WBCSolution
from mbctl.control.wbc.contacts import ContactState, FootContact
from mbctl.control.wbc.joint_limits import JointLimitBounds
from mbctl.control.wbc.qp import WholeBodyQP
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.indexing import as_slice
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


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
                                                    slice(cols.start + 2, cols.stop, 3))
            col = cols.stop
        self.n_x = col
        self._points_F = {name: cs.contact.points_F for name, cs in self.contacts.items()}
        self._force_slices = {name: slice(cs.cols.start - nv, cs.cols.stop - nv)
                              for name, cs in self.contacts.items()}
        n_f = col - nv
        n_feet = len(self.contacts)
        self._n_fric = 4 * n_f // 3 + 2 * n_feet  # the pyramids, then each foot's torsion
        n_a, n_u, n_feet_rows = len(self._act), self._n_unact, 6 * n_feet
        # the QP's rows, one buffer: the feet's rows and the base's dynamics rows (the equalities,
        # the last n_u with force columns), the torque rows, the friction pyramids and the feet's
        # torsion (the inequalities); [M, -Jc^T]'s rows [u; a] are one block of it
        self._qp = WholeBodyQP(nv, n_f, n_a + self._n_fric, n_feet_rows + n_u, self._config.force_weight,
                               m_force=n_u)
        qp = self._qp
        self._n_feet_rows = n_feet_rows
        self._dyn = qp.rows[n_feet_rows:n_feet_rows + nv]  # [M, -Jc^T], rows u then a
        self._T = qp.G[:n_a]  # torque rows: tau = T x + b_a (its rows a, written each cycle)
        qp.deferred_rows = slice(0, n_a)  # the torque limits: rarely active
        # M's and -Jc^T's rows in order when the unactuated dofs come first (a free flyer's), else
        # picked by index
        in_order = isinstance(self._u, slice) and isinstance(self._a, slice) \
            and (self._u.start, self._u.stop, self._a.start, self._a.stop) == (0, n_u, n_u, nv)
        self._dyn_rows = None if in_order else np.concatenate([self._unact, self._act])
        # views made once (no slices per cycle): M's block of [M, -Jc^T], the base rows' targets, the
        # torque rows' bounds and, where the dofs are slices, the bias forces' rows u and a
        self._D_M, self._e_dyn = self._dyn[:, :nv], qp.e[n_feet_rows:n_feet_rows + n_u]
        self._tau_up, self._tau_lo = qp.g_up[:n_a], qp.g_lo[:n_a]
        b = self.state.b  # (Pinocchio writes data.nle in place)
        self._b_u_a = (b[self._u], b[self._a]) if isinstance(self._u, slice) and isinstance(self._a, slice) \
            else None
        row = n_a
        for cs in self.contacts.values():  # friction pyramid rows: |f_x|, |f_y| <= mu / sqrt(2) f_z
            mu = cs.contact.mu / np.sqrt(2.0)
            for c0 in range(cs.cols.start, cs.cols.stop, 3):
                for axis in (0, 1):
                    for sign in (1.0, -1.0):
                        qp.G[row, c0 + axis] = sign
                        qp.G[row, c0 + 2] = -mu
                        qp.g_up[row] = 0.0
                        row += 1
        # torsion rows (their f_z terms written by the config setter): +-M_z - torsion_m sum f_z <= 0
        # with M_z = sum (p - c)_x f_y - (p - c)_y f_x about the sole's centre c, in F
        self._torsion_rows = []
        for cs in self.contacts.values():
            r = cs.contact.points_F - cs.contact.points_F.mean(axis=0)
            moment = np.zeros(self.n_x)
            moment[cs.cols.start:cs.cols.stop:3] = -r[:, 1]
            moment[cs.cols.start + 1:cs.cols.stop:3] = r[:, 0]
            self._torsion_rows.append((row, moment, cs.fz))
            qp.g_up[row:row + 2] = 0.0
            row += 2
        # the points' Jacobians in their foot frames, transposed and negated: -Jc^T = J_F^T (-G_blk^T),
        # one product whose rows are the dynamics' and the torque rows' force columns
        self._JcT_neg = np.zeros((nv, n_f))
        # every foot's LOCAL Jacobian, stacked, copied into its rows of E (a buffer of its own: np.dot
        # copies a strided operand first, ~1.4 us more for the two products with J_F)
        self._JF, self._JF_E = np.zeros((n_feet_rows, nv)), qp.E[:n_feet_rows, :nv]
        self._foot_err = qp.e[:n_feet_rows]  # each foot's row targets (see compute)
        self._packed = False  # a foot's rows were moved over another's (their force columns to clear)
        self._G_blk = np.zeros((n_f, n_feet_rows))  # Jc = blockdiag(G_F) J_F, one product
        for i, cs in enumerate(self.contacts.values()):
            self._G_blk[cs.cols.start - nv:cs.cols.stop - nv, 6 * i:6 * i + 6] = cs.G_F
        # each foot's rows of J_F and its row targets: views made once (no slices per cycle)
        self._foot_rows = tuple((name, cs, self._JF[6 * i:6 * i + 6], self._foot_err[6 * i:6 * i + 6])
                                for i, (name, cs) in enumerate(self.contacts.items()))
        self._GT_neg = -self._G_blk.T  # (negation is exact: the same products as -(G_blk J_F))
        self._wrench_map = self._G_blk.T  # the solutions' (a read-only view, made once)
        self._wrench_map.setflags(write=False)
        self._limits = JointLimitBounds(self.model, self._act)
        self.config = self._config  # the setter derives the config's terms
        self._stack = TaskStack(nv)
        self.last: WBCSolution | None = None
        #: Cycles solved by the equality-constrained fast path / by daqp (see control/wbc/qp.py).
        self.fast_path_cycles = 0
        self.daqp_cycles = 0
        #: Cycles solved only without the joint-limit bounds (``WBCConfig.relax_joint_limits``).
        self.relaxed_cycles = 0
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
        self._qp.force_weight = config.force_weight
        self._qp.use_force_space = config.force_space
        G, bounded = self._qp.G, math.isfinite(config.torsion_m)
        for row, moment, fz in self._torsion_rows:
            G[row:row + 2] = 0.0  # unbounded: 0 <= 0
            if bounded:
                G[row], G[row + 1] = moment, -moment
                G[row:row + 2, fz] = -config.torsion_m
        #: the weight each foot's force bounds were last written with (None: rewrite them)
        self._bound_weight: dict[str, float | None] = dict.fromkeys(self.contacts)
        self._limits.configure(config)
        # the feet's slip feedback: kp on each foot's x, y and yaw rows, 0 on z, roll and pitch
        self._foot_gain = np.array([1.0, 1.0, 0.0, 0.0, 0.0, 1.0]) * config.contact_omega_rad_s**2

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
        """Forget the ramp clock, the fallback and the counters (the tasks and contacts stay)."""
        self._last_time_s = None
        self.fast_path_cycles = self.daqp_cycles = self.relaxed_cycles = 0
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
        nv = self.model.nv
        cfg = self.config
        qp = self._qp
        # tasks: H_vv = W^T W + w_r^2 I, c_v = -W^T r (the task layer's stack)
        self._stack.acceleration_objective(s, qp.H_vv, qp.c_v, cfg.acceleration_weight**2)

        # contact points' Jacobians, in their foot frame F: J_P = G_F J_F (J_F LOCAL)
        lb, ub = qp.lb, qp.ub
        JF, err, gain = self._JF, self._foot_err, self._foot_gain
        poses: list[np.ndarray] = []  # the solution's X_WF (the state's are overwritten by the next update)
        all_active = True
        # Pinocchio's getters on the state's data directly (the state's wrappers add ~0.7 us for both feet)
        LOCAL, model, data, placements = pin.LOCAL, s.model, s.data, s.frame_placements
        for name, cs, JF_rows, err_rows in self._foot_rows:
            X_WF = placements[cs.fid]
            poses.append(X_WF.homogeneous)  # a new array (a list of them: ~0.3 us, an array of them ~1)
            JF_rows[:] = pin.getFrameJacobian(model, data, cs.fid, LOCAL)
            if self._bound_weight[name] != cs.weight:  # changes only while a force ramps
                lb[cs.fz] = cs.weight * cfg.f_min_n
                ub[cs.fz] = cs.weight * cfg.f_max_n
                # a foot at weight 0: its forces are pinned at zero (bounds [0, 0], the pyramid)
                qp.force_free[cs.cols.start - nv:cs.cols.stop - nv] = cs.weight * cfg.f_max_n != 0.0
                self._bound_weight[name] = cs.weight
            if cs.active:  # kp S log6(X_FF0) - Jdot_F v (its - kd J_F v below, both feet in one product)
                np.multiply(pin.log6(X_WF.actInv(cs.X_WF0)).vector, gain, out=err_rows)
                err_rows -= pin.getFrameAcceleration(model, data, cs.fid, LOCAL).vector
            else:  # no row for this foot
                all_active = False
        JcT_neg = self._JcT_neg
        np.dot(JF.T, self._GT_neg, out=JcT_neg)
        np.copyto(self._JF_E, JF)
        # each active foot's twist in F: J_F vdot + Jdot_F v = kp S log6(X_FF0) - kd J_F v, with S
        # keeping x, y and yaw (the ground sets height, roll and pitch; feedback corrects slip only)
        # err -= kd J_F v in place by one BLAS call, y = alpha A x + beta y (positional: beta, y, offx,
        # incx, offy, incy, trans, overwrite_y; J_F^T is Fortran-contiguous): np.dot, a scaling and a
        # subtraction cost ~1.7 us more
        dgemv(-2.0 * cfg.contact_omega_rad_s, JF.T, s.v, 1.0, err, 0, 1, 0, 1, 1, 1)
        # [M, -Jc^T]: its rows u are the base's dynamics rows M_u vdot - Jc_u^T f = -b_u (equalities),
        # its rows a the torque rows, tau = T x + b_a with T = [M_a, -Jc_a^T]; tau_min <= tau <= tau_max
        D = self._dyn
        if self._dyn_rows is None:
            s.mass_matrix_into(self._D_M)
            D[:, nv:] = JcT_neg
        else:
            D[:, :nv] = s.M[self._dyn_rows]
            D[:, nv:] = JcT_neg[self._dyn_rows]
        n_u, n_feet_rows = self._n_unact, self._n_feet_rows
        m_eq = n_feet_rows + n_u
        E, e = qp.E, qp.e
        b_u, b_a = self._b_u_a or (s.b[self._u], s.b[self._a])
        np.negative(b_u, out=self._e_dyn)
        np.subtract(self.tau_high, b_a, out=self._tau_up)
        np.subtract(self.tau_low, b_a, out=self._tau_lo)
        if self._packed:  # rows the last cycle moved: the feet's rows have no force columns
            E[:n_feet_rows, nv:] = 0.0
            self._packed = False
        if not all_active:  # the active feet's rows, then the dynamics rows, moved up to the top
            k = 0
            for i, cs in enumerate(self.contacts.values()):
                if cs.active:
                    if k != i:
                        E[6 * k:6 * k + 6], e[6 * k:6 * k + 6] = E[6 * i:6 * i + 6], e[6 * i:6 * i + 6]
                    k += 1
            E[6 * k:6 * k + n_u], e[6 * k:6 * k + n_u] = E[n_feet_rows:m_eq], e[n_feet_rows:m_eq]
            m_eq = 6 * k + n_u
            self._packed = True
        # joint limits: q + v T + vdot T^2/2 within [q_min + margin, q_max - margin] (joint_limits.py)
        n_limits = len(self._limits)
        if n_limits:
            self._limits.write(s.qv, lb, ub)
        t_qp = time.perf_counter()
        result = self._solve(m_eq)
        if result.x is None and cfg.relax_joint_limits and n_limits:
            result = self._solve_relaxed(m_eq)
        qp_time = time.perf_counter() - t_qp
        x = result.x
        if x is None:  # (the floor gives a finite x or None)
            relaxed = cfg.relax_joint_limits and n_limits
            what = (
                f"whole-body QP infeasible at step {self.steps} (solver {cfg.solver}"
                + (", also without the joint-limit bounds" if relaxed else "")
                + "): contacts "
                + ", ".join(f"{n} weight {cs.weight:.2f}" for n, cs in self.contacts.items())
                + f"; normal force per point {cfg.f_min_n:g} to {cfg.f_max_n:g} N at full weight; "
                f"torque limits [{self.tau_low.min():.1f}, {self.tau_high.max():.1f}] N m")
            error = infeasible_error(WBCInfeasible, what, "Check the force bounds and torque limits against "
                                     "the load, the friction and the task targets.", qp.data(m_eq), result,
                                     cfg.solver, time_s=state.time_s)
            if cfg.on_infeasible == "raise":
                raise error
            self.infeasible_at_s, self.infeasible_message = state.time_s, str(error)
            return self._fallback(state, t0)
        Gx = qp.Gx  # G x when the solve computed it (its check): its first rows are T x
        if Gx is not None:
            tau = np.add(Gx[:len(b_a)], b_a)
        else:
            tau = np.dot(self._T, x)
            tau += b_a
        if cfg.friction_feedforward:
            self._add_friction(tau, x[:nv], dt_s)
        self.steps += 1
        command = Command(CommandKind.TORQUE, tau, self._command_names)
        # the time of the whole compute, the command included (its record, ~1 us, after the stamp)
        self.last = WBCSolution(tau, x[:nv], x[nv:], self._force_slices, self._points_F, tuple(poses),
                                self._wrench_map, time.perf_counter() - t0, qp_time)
        return command

    def _solve(self, m_eq: int) -> QPResult:
        """The QP as filled, by the configured solver (counting fast-path and daqp cycles)."""
        qp = self._qp
        if self.config.solver != "daqp":  # another backend, through qpsolvers (for comparison)
            return qp.solve_with(self.config.solver, m_eq)
        result = qp.solve(m_eq)
        if result.fast_path:
            self.fast_path_cycles += 1
        else:
            self.daqp_cycles += 1
        return result

    def _solve_relaxed(self, m_eq: int) -> QPResult:
        """The QP again without the joint-limit acceleration bounds (restored after); counted if solved."""
        iv, lb, ub = self._limits.index, self._qp.lb, self._qp.ub
        saved = lb[iv].copy(), ub[iv].copy()
        lb[iv], ub[iv] = -np.inf, np.inf
        result = self._solve(m_eq)
        lb[iv], ub[iv] = saved
        if result.x is not None:
            self.relaxed_cycles += 1
        return result

    def _add_friction(self, tau: np.ndarray, vdot: np.ndarray, dt_s: float) -> None:
        """``tau += f_c tanh(v_plan / speed) + d v_plan``, ``v_plan = v + vdot dt``; clamped to the limits."""
        a = self._a
        v_plan = self.state.v[a] + vdot[a] * dt_s
        coulomb, viscous = self.model.friction[self._act], self.model.damping[self._act]
        tau += coulomb * np.tanh(v_plan / self._config.friction_speed_rad_s) + viscous * v_plan
        np.clip(tau, self.tau_low, self.tau_high, out=tau)

    def _fallback(self, state: RobotState, t0: float) -> Command:
        """Joint damping ``tau = -kd v`` within the torque limits (the ``on_infeasible="damp"`` fallback)."""
        tau = -self._config.fallback_kd_n_m_s_rad * np.asarray(state.v)[self._a]
        np.maximum(tau, self.tau_low, out=tau)
        np.minimum(tau, self.tau_high, out=tau)
        poses = tuple(self.state.frame_pose(cs.fid).homogeneous for cs in self.contacts.values())
        self.steps += 1
        command = Command(CommandKind.TORQUE, tau, self._command_names)
        self.last = WBCSolution(tau, np.full(self.model.nv, np.nan), np.zeros(self.n_x - self.model.nv),
                                self._force_slices, self._points_F, poses, self._wrench_map,
                                time.perf_counter() - t0, 0.0, fallback=True)
        return command
