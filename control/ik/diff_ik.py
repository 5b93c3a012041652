"""Differential IK as a QP on Pinocchio Jacobians, solved through ``qpsolvers.solve_problem``.

Each step solves, for the tangent step ``dq`` (nv,) (``v = dq / dt``)::

    min_dq  1/2 dq^T H dq + c^T dq
    s.t.    G dq <= h,   lb <= dq <= ub

    H = W^T W + (damping + sum_i mu_i) I,   c = -W^T r,
    W = [diag(cost_i) J_i]_i (stacked),    r = [-gain_i diag(cost_i) e_i]_i,
    mu_i = lm_damping_i |r_i|^2

which is mink's problem (``mink.solve_ik``) written with Pinocchio quantities; the task rows are
the velocity level of :mod:`mbctl.control.tasks` (assembled by its ``TaskStack``). The step is
applied on the manifold with ``pin.integrate``.

``DiffIK`` preallocates W, r, H, c and the bounds for a fixed task/limit set; one step costs one
``pin.computeJointJacobians`` + ``pin.updateFramePlacements`` (+ CoM) and one QP.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import qpsolvers
from qpsolvers.warnings import SparseConversionWarning

from mbctl.control.exceptions import IKInfeasible, IKSetupError
from mbctl.control.ik.limits import BoxLimit, Limit
from mbctl.control.ik.loop import IKResult, iterate
from mbctl.control.tasks.base import Task
from mbctl.control.tasks.com import ComTask
from mbctl.control.tasks.residuals import TaskResidual, Tolerance
from mbctl.control.tasks.stack import TaskStack
from mbctl.control.tasks.state import KinematicState

#: Magnitude standing for "no bound" in the QP (DAQP's and OSQP's infinity).
QP_INFINITY = 1e30


class IKStep(NamedTuple):
    """One differential-IK step.

    Attributes:
        v: Tangent velocity (nv,) = dq / dt, Pinocchio convention (base twist in the base frame).
        dq: Tangent step (nv,).
        solve_time_s: Time spent in the QP backend [s] (as reported by qpsolvers).
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
    ):
        """Allocate the QP buffers.

        Args:
            model: Pinocchio model.
            tasks: Tasks (non-empty).
            limits: Limits; box limits become QP bounds, others inequality rows.
            solver: Any backend in ``qpsolvers.available_solvers``.
            damping: Global LM damping (>= 0) on all dofs, floating base included.
            solver_options: Keyword arguments for the backend (e.g. OSQP tolerances).

        Raises:
            IKSetupError: No tasks, an unavailable solver, or negative damping.
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
        self.stack = TaskStack(nv, self.tasks)
        self._H = np.zeros((nv, nv))
        self._H_diag = np.einsum("ii->i", self._H)  # writable view of H's diagonal
        self._c = np.zeros(nv)
        self._box = tuple(lim for lim in self.limits if isinstance(lim, BoxLimit))
        self._box_dynamic = tuple(lim for lim in self._box if lim.state_dependent)
        self._box_static = tuple(lim for lim in self._box if not lim.state_dependent)
        self._other = tuple(lim for lim in self.limits if not isinstance(lim, BoxLimit))
        self._lb = np.empty(nv)
        self._ub = np.empty(nv)
        self._static_dt: float | None = None
        self._static_lb = np.empty(nv)
        self._static_ub = np.empty(nv)
        self._quiet = solver == "osqp"

    # ------------------------------------------------------------------ QP
    def update(self, q: npt.ArrayLike) -> None:
        """Move the kinematic state to ``q`` (nq,)."""
        self.state.update(q)

    def _bounds(self, dt: float) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        if not self._box:
            return None, None
        if self._static_dt != dt:
            self._static_lb.fill(-QP_INFINITY)
            self._static_ub.fill(QP_INFINITY)
            for lim in self._box_static:
                lim.intersect_bounds(self.state, dt, self._static_lb, self._static_ub)
            self._static_dt = dt
        lb, ub = self._lb, self._ub
        np.copyto(lb, self._static_lb)
        np.copyto(ub, self._static_ub)
        for lim in self._box_dynamic:
            lim.intersect_bounds(self.state, dt, lb, ub)
        return lb, ub

    def build_problem(self, dt: float) -> qpsolvers.Problem:
        """The QP at the current state for a step of ``dt`` [s] (buffers are reused: copy to keep).

        Raises:
            IKSetupError: ``dt`` not positive; a task without a target.
        """
        if not dt > 0.0:
            raise IKSetupError(f"dt must be > 0 [s]; got {dt!r}")
        state = self.state
        H = self._H
        mu = self.damping + self.stack.velocity_objective(state, H, self._c)
        self._H_diag += mu
        lb, ub = self._bounds(dt)
        G = h = None
        if self._other:
            cons = [lim.compute_qp_inequalities(state, dt) for lim in self._other]
            G = np.vstack([con.G for con in cons])
            h = np.concatenate([con.h for con in cons])
        return qpsolvers.Problem(H, self._c, G, h, None, None, lb, ub)

    def solve_step(self, dt: float = 1.0) -> IKStep:
        """Solve the QP at the current state.

        Args:
            dt: Step duration [s] (scales velocity limits; ``v = dq / dt``).

        Raises:
            IKInfeasible: The backend found no solution (carries the QP and the result).
        """
        problem = self.build_problem(dt)
        if self._quiet and problem.lb is not None and (problem.lb > problem.ub).any():
            # Contradictory boxes (q outside its limits): OSQP refuses such data outright
            # (daqp reports them as infeasible, which _infeasible then diagnoses).
            result = qpsolvers.Solution(problem)
            result.found = False
            raise self._infeasible(problem, result)
        if self._quiet:
            with warnings.catch_warnings():
                # OSQP wants a sparse P; qpsolvers converts our dense one and says so each call.
                warnings.simplefilter("ignore", SparseConversionWarning)
                # osqp 1.x announces a future default; a failed solve raises IKInfeasible.
                warnings.filterwarnings("ignore", message="The default value of raise_error")
                warnings.filterwarnings("ignore", message="OSQP exited with status")
                result = qpsolvers.solve_problem(problem, solver=self.solver, **self.solver_options)
        else:
            result = qpsolvers.solve_problem(problem, solver=self.solver, **self.solver_options)
        if not result.found or result.x is None:
            raise self._infeasible(problem, result)
        dq = result.x
        return IKStep(dq / dt, dq, float(result.solve_time or 0.0))

    def _infeasible(self, problem: qpsolvers.Problem, result: qpsolvers.Solution) -> IKInfeasible:
        lb, ub = problem.lb, problem.ub
        if lb is not None and ub is not None and np.any(lb > ub):
            bad = np.flatnonzero(lb > ub)
            message = (
                f"IK limits contradict each other at dofs {bad[:8].tolist()}: lower bounds "
                f"{lb[bad[:8]].round(6).tolist()} exceed upper bounds "
                f"{ub[bad[:8]].round(6).tolist()} (is q outside its joint limits?). "
                "Move q inside its limits or relax the limits."
            )
        else:
            message = (
                f"QP solver {self.solver!r} found no IK step (the limits may be infeasible); "
                "inspect .problem and .result."
            )
        return IKInfeasible(message, _copy_problem(problem), result, self.solver)

    def step(self, q: npt.ArrayLike, dt: float = 1.0) -> IKStep:
        """Update the state to ``q`` (nq,) and solve one step."""
        self.state.update(q)
        return self.solve_step(dt)

    # ------------------------------------------------------------------ loop
    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""
        return np.array(self.state.q)

    def task_residuals(self) -> dict[str, TaskResidual]:
        """Every task's residual at the current state, by task name."""
        return {t.name: t.residual(self.state) for t in self.tasks}

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

    @property
    def q(self) -> np.ndarray:
        return self.ik.q

    def advance(self) -> float:
        ik = self.ik
        out = ik.solve_step(self.dt)
        ik.update(pin.integrate(ik.model, ik.state.q, out.dq))
        return float(np.max(np.abs(out.dq)))


def _copy_problem(p: qpsolvers.Problem) -> qpsolvers.Problem:
    def cp(x):
        return None if x is None else np.array(x, copy=True)

    return qpsolvers.Problem(cp(p.P), cp(p.q), cp(p.G), cp(p.h), cp(p.A), cp(p.b), cp(p.lb), cp(p.ub))


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
