"""Differential IK as a QP on Pinocchio Jacobians, with optional strict task priorities.

Each step solves, for the tangent step ``dq`` (nv,) (``v = dq / dt``)::

    min_dq  1/2 dq^T H dq + c^T dq
    s.t.    G dq <= h,   lb <= dq <= ub

    H = W^T W + (damping + sum_i mu_i) I,   c = -W^T r,
    W = [diag(cost_i) J_i]_i (stacked),    r = [-gain_i diag(cost_i) e_i]_i,
    mu_i = lm_damping_i |r_i|^2

which is mink's problem (``mink.solve_ik``) written with Pinocchio quantities; the task rows are
the velocity level of :mod:`mbctl.control.tasks` (assembled by its ``TaskStack``). The step is
applied on the manifold with ``pin.integrate``. The QP is solved by the control layer's QP floor,
:mod:`mbctl.control.qp` (daqp directly, other backends through qpsolvers).

Priorities. Tasks may be given levels (0 highest). The step is then a lexicographic solve: one QP
per level, level k minimising its own tasks' least squares under the limits AND the equality
``W_j dq = W_j dq_{k-1}`` for every level j above, i.e. the task velocities the levels above
achieved. Equality on achieved task velocities, not null-space projection, because the limits
are inequalities: a projector ``N`` of the upper levels' Jacobians would turn every joint bound
into a dense inequality in the projected variable and, used without re-solving, lets a lower
level push a joint through its bound; with the equality every level keeps the same variable,
the same bounds, the same collision rows, and the upper levels' optimum exactly. The equality
rows are an orthonormal basis of the upper rows' span (an SVD), so dependent tasks add no
redundant rows for the solver to trip on. Regularisers (posture, damping) belong to the last
level. One level is the weighted QP above.

``DiffIK`` preallocates W, r, H, c and the bounds for a fixed task/limit set; one step costs one
Pinocchio pass for the joint Jacobians (with the CoM's when a task needs it,
``pin.jacobianCenterOfMass``; else ``pin.computeJointJacobians``) + ``pin.updateFramePlacements``
and one QP per level.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import qpsolvers

from mbctl.control.exceptions import IKInfeasible, IKSetupError
from mbctl.control.ik.limits import BoxLimit, Limit
from mbctl.control.ik.loop import IKResult, iterate
from mbctl.control.qp import CONTRADICTORY, QP_INFINITY, QPData, QPResult, QPSolver, infeasible_error
from mbctl.control.tasks.base import Task
from mbctl.control.tasks.com import ComTask
from mbctl.control.tasks.residuals import TaskResidual, Tolerance
from mbctl.control.tasks.stack import TaskStack
from mbctl.control.tasks.state import KinematicState

#: Singular values of the upper levels' rows below this fraction of the largest are not frozen
#: (directions those tasks do not really constrain).
RANK_RTOL = 1e-9

__all__ = ["QP_INFINITY", "DiffIK", "IKStep", "solve_ik"]


class IKStep(NamedTuple):
    """One differential-IK step.

    Attributes:
        v: Tangent velocity (nv,) = dq / dt, Pinocchio convention (base twist in the base frame).
        dq: Tangent step (nv,).
        solve_time_s: Time spent in the QP backend [s], every level's solve summed.
    """

    v: np.ndarray
    dq: np.ndarray
    solve_time_s: float


class DiffIK:
    """Differential-IK QP for a fixed set of tasks and limits, with preallocated buffers.

    Attributes:
        model: Pinocchio model.
        tasks: The tasks (targets may change between steps; the set may not).
        limits: The limits (built once by the caller).
        solver: qpsolvers backend name (e.g. "daqp", "osqp").
        damping: Global Levenberg-Marquardt term added to H's diagonal [cost].
        state: Kinematic state at the last ``update``.
    """

    def __init__(
        self,
        model: pin.Model,
        tasks: Sequence[Task],
        limits: Sequence[Limit] = (),
        solver: str = "daqp",
        damping: float = 1e-12,
        solver_options: dict | None = None,
        levels: Sequence[int] | None = None,
    ):
        """Allocate the QP buffers.

        Args:
            model: Pinocchio model.
            tasks: Tasks (non-empty).
            limits: Limits; box limits become QP bounds, others inequality rows.
            solver: Any backend in ``qpsolvers.available_solvers``.
            damping: Global LM damping (>= 0) on all dofs, floating base included, every level.
            solver_options: Keyword arguments for the backend (e.g. OSQP tolerances).
            levels: Priority level of each task (0 highest; the levels used must be 0..L-1);
                None puts every task in one weighted level.

        Raises:
            IKSetupError: No tasks, an unavailable solver, negative damping, or levels that do not
                match the tasks (a gap, a negative level, a regulariser above the last level).
        """
        if not tasks:
            raise IKSetupError("DiffIK needs at least one task.")
        if solver not in qpsolvers.available_solvers:
            raise IKSetupError(
                f"QP solver {solver!r} is not installed; available: "
                f"{', '.join(sorted(qpsolvers.available_solvers))}."
            )
        if not (np.isfinite(damping) and damping >= 0.0):
            raise IKSetupError(f"damping must be >= 0; got {damping!r}")
        self.model = model
        self.tasks = tuple(tasks)
        self.limits = tuple(limits)
        self.solver = solver
        self.damping = float(damping)
        self.solver_options = dict(solver_options or {})
        if solver == "osqp" and not self.solver_options:
            self.solver_options = {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": False}
        self.state = KinematicState(model, with_com=any(isinstance(t, ComTask) for t in self.tasks))
        nv = model.nv
        level_of = _check_levels(self.tasks, levels)
        n_levels = max(level_of) + 1
        #: Tasks by priority level, level 0 first.
        self.levels: tuple[tuple[Task, ...], ...] = tuple(
            tuple(t for t, k in zip(self.tasks, level_of, strict=True) if k == level)
            for level in range(n_levels))
        self.stacks = tuple(TaskStack(nv, level) for level in self.levels)
        self._H = np.zeros((nv, nv))
        self._H_diag = np.einsum("ii->i", self._H)  # writable view of H's diagonal
        self._c = np.zeros(nv)
        self._box = tuple(lim for lim in self.limits if isinstance(lim, BoxLimit))
        self._box_dynamic = tuple(lim for lim in self._box if lim.state_dependent)
        self._box_static = tuple(lim for lim in self._box if not lim.state_dependent)
        self._other = tuple(lim for lim in self.limits if not isinstance(lim, BoxLimit))
        self._guards = tuple(lim for lim in self.limits if type(lim).guard_step is not Limit.guard_step)
        # lower and upper bounds as the rows of one buffer (each row contiguous): one copy a step
        self._bounds_buffer = np.empty((2, nv))
        self._lb, self._ub = self._bounds_buffer
        self._static_dt: float | None = None
        self._static_bounds = np.empty((2, nv))
        self._static_lb, self._static_ub = self._static_bounds
        self._qp = QPSolver(nv, solver, self.solver_options)

    # ------------------------------------------------------------------ QP
    def update(self, q: npt.ArrayLike) -> None:
        """Move the kinematic state to ``q`` (nq,)."""
        self.state.update(q)

    def _bounds(self, dt: float) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        if not self._box:
            return None, None
        if self._static_dt != dt:  # boxes that depend on dt only: once per dt
            self._static_lb.fill(-QP_INFINITY)
            self._static_ub.fill(QP_INFINITY)
            for lim in self._box_static:
                lim.intersect_bounds(self.state, dt, self._static_lb, self._static_ub)
            self._static_dt = dt
        lb, ub = self._lb, self._ub
        np.copyto(self._bounds_buffer, self._static_bounds)
        for lim in self._box_dynamic:
            lim.intersect_bounds(self.state, dt, lb, ub)
        return lb, ub

    def _inequalities(self, dt: float) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        if not self._other:
            return None, None
        cons = [con for con in (lim.compute_qp_inequalities(self.state, dt) for lim in self._other)
                if con.G.shape[0]]
        if not cons:
            return None, None
        if len(cons) == 1:
            return cons[0].G, cons[0].h
        return np.vstack([con.G for con in cons]), np.concatenate([con.h for con in cons])

    def _objective(self, level: int) -> tuple[np.ndarray, np.ndarray]:
        H = self._H
        mu = self.damping + self.stacks[level].velocity_objective(self.state, H, self._c)
        self._H_diag += mu
        return H, self._c

    def build_problem(self, dt: float) -> qpsolvers.Problem:
        """The (first level's) QP at the current state for a step of ``dt`` [s], as copies.

        Raises:
            IKSetupError: ``dt`` not positive; a task without a target.
        """
        _check_dt(dt)
        lb, ub = self._bounds(dt)
        G, h = self._inequalities(dt)
        H, c = self._objective(0)
        return QPData(H, c, lb, ub, G, h, None, None).problem()

    def solve_step(self, dt: float = 1.0) -> IKStep:
        """Solve the QP (one per priority level) at the current state.

        Args:
            dt: Step duration [s] (scales velocity limits; ``v = dq / dt``).

        Raises:
            IKSetupError: ``dt`` not positive; a task without a target.
            IKInfeasible: The backend found no solution (carries the QP and the result).
        """
        _check_dt(dt)
        lb, ub = self._bounds(dt)
        G, h = self._inequalities(dt)
        A = b = None
        solve_time = 0.0
        last = len(self.stacks) - 1
        for level in range(last + 1):
            H, c = self._objective(level)
            qp = QPData(H, c, lb, ub, G, h, A, b)
            out = self._qp.solve(qp)
            solve_time += out.solve_time_s
            if out.x is None:
                raise self._infeasible(qp, out, level)
            dq = out.x
            if level < last:
                A, b = self._freeze(level, dq)
        return IKStep(dq / dt, dq, solve_time)

    def _freeze(self, level: int, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Equality rows keeping the task velocities of levels 0..level at what ``dq`` achieves."""
        W = np.vstack([self.stacks[k].velocity_rows()[0] for k in range(level + 1)])
        if not W.shape[0]:
            return np.zeros((0, self.model.nv)), np.zeros(0)
        _, s, Vt = np.linalg.svd(W, full_matrices=False)
        basis = Vt[: int(np.sum(s > RANK_RTOL * s[0]))] if s[0] > 0.0 else Vt[:0]
        return basis, basis @ dq

    def _infeasible(self, qp: QPData, out: QPResult, level: int) -> IKInfeasible:
        where = f" at priority level {level}" if len(self.stacks) > 1 else ""
        if out.status == CONTRADICTORY and qp.lb is not None and qp.ub is not None \
                and np.any(qp.lb > qp.ub):
            bad = np.flatnonzero(qp.lb > qp.ub)[:8].tolist()
            what = f"IK limits contradict each other{where} at dofs {bad} (is q outside its joint limits?)"
            advice = "Move q inside its limits or relax the limits."
        else:
            what = f"QP solver {self.solver!r} found no IK step{where} (the limits may be infeasible)"
            advice = "Inspect .problem and .result."
        return infeasible_error(IKInfeasible, what, advice, qp, out, self.solver)

    def step(self, q: npt.ArrayLike, dt: float = 1.0) -> IKStep:
        """Update the state to ``q`` (nq,) and solve one step."""
        self.state.update(q)
        return self.solve_step(dt)

    def advance(self, dt: float = 1.0) -> float:
        """Solve a step at the current state, let the limits guard it, move there; its ``|dq|_inf``.

        Raises:
            IKSetupError: ``dt`` not positive; a task without a target.
            IKInfeasible: The QP has no solution.
        """
        dq = self.solve_step(dt).dq
        q = self.state.q
        for lim in self._guards:
            dq = lim.guard_step(self.model, q, dq)
        self.state.update(pin.integrate(self.model, q, dq))
        return float(np.maximum.reduce(np.abs(dq)))  # np.max without its Python wrapper (~1 us)

    # ------------------------------------------------------------------ loop
    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""
        return np.array(self.state.q)

    def task_residuals(self) -> dict[str, TaskResidual]:
        """Every task's residual at the current state, by task name."""
        return {t.name: t.residual(self.state) for t in self.tasks}

    @property
    def level_names(self) -> tuple[tuple[str, ...], ...]:
        """Task names by priority level, level 0 first."""
        return tuple(tuple(t.name for t in level) for level in self.levels)

    def solve(
        self,
        q0: npt.ArrayLike,
        dt: float = 1.0,
        tolerance: Tolerance | None = None,
        max_iters: int = 50,
        step_tol: float = 1e-6,
    ) -> IKResult:
        """Iterate steps from ``q0`` (nq,) until every target task meets ``tolerance``.

        Args:
            q0: Initial configuration (nq,).
            dt: Step duration [s] (velocity limits allow ``v_max dt`` per step).
            tolerance: Position [m] and orientation [rad] tolerances (default 1 mm, 0.01 rad).
            max_iters: Maximum number of steps.
            step_tol: Stop when ``|dq|_inf`` falls below this [rad or m].

        Raises:
            IKSetupError: A non-positive ``dt``, negative ``step_tol`` or ``max_iters`` < 1.
            IKInfeasible: A step's QP has no solution.
        """
        return iterate(_Stepper(self, dt), q0, tolerance or Tolerance(), max_iters, step_tol)


class _Stepper:
    """``DiffIK`` as an :class:`~mbctl.control.ik.loop.IKStepper` with a fixed step duration."""

    def __init__(self, ik: DiffIK, dt: float):
        self.ik, self.dt = ik, dt
        self.update = ik.update
        self.task_residuals = ik.task_residuals
        self.levels = ik.level_names

    @property
    def q(self) -> np.ndarray:
        return self.ik.q

    def advance(self) -> float:
        return self.ik.advance(self.dt)


def _check_dt(dt: float) -> None:
    if not dt > 0.0:
        raise IKSetupError(f"dt must be > 0 [s]; got {dt!r}")


def _check_levels(tasks: tuple[Task, ...], levels: Sequence[int] | None) -> list[int]:
    """Each task's level, checked: 0..L-1 all used, regularisers in the last level.

    Raises:
        IKSetupError: The levels do not fit the tasks (the message names the task).
    """
    if levels is None:
        return [0] * len(tasks)
    level_of = [int(k) for k in levels]
    if len(level_of) != len(tasks) or any(k < 0 or k != levels[i] for i, k in enumerate(level_of)):
        raise IKSetupError(f"levels must be one non-negative integer per task ({len(tasks)}); got "
                           f"{list(levels)!r}")
    used = sorted(set(level_of))
    if used != list(range(len(used))):
        raise IKSetupError(f"priority levels must be 0, 1, ... without gaps; got {used}")
    last = used[-1]
    for task, k in zip(tasks, level_of, strict=True):
        if task.regularizing and k != last:
            raise IKSetupError(f"{task.name!r} is a regulariser: it belongs to the last level ({last}), "
                               f"not level {k} (it would fix every dof for the levels below)")
    return level_of


def solve_ik(
    state: KinematicState,
    tasks: Sequence[Task],
    dt: float,
    solver: str = "daqp",
    damping: float = 1e-12,
    limits: Sequence[Limit] = (),
) -> np.ndarray:
    """One differential-IK step at ``state`` (mink's ``solve_ik`` signature, Pinocchio side).

    Convenience for one-off calls: it allocates a ``DiffIK`` each time; loops should keep one.

    Args:
        state: Kinematic state (its ``q`` is used).
        tasks: Tasks with targets set.
        dt: Step duration [s].
        solver: qpsolvers backend.
        damping: Global LM damping.
        limits: Limits.

    Returns:
        Tangent velocity ``v`` (nv,), Pinocchio convention.

    Raises:
        IKInfeasible: The QP has no solution.
        IKSetupError: Invalid arguments.
    """
    ik = DiffIK(state.model, tasks, limits, solver, damping)
    return ik.step(state.q, dt).v
