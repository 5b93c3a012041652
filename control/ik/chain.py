"""Damped least squares on one kinematic chain (a leg, an arm): its joints move, the rest is held.

The tasks are those of :mod:`mbctl.control.tasks` (e.g. a foot's
:class:`~mbctl.control.tasks.frame_pose.FramePoseTask`); only the tangent indices S of the chain's
joints move, the floating base and every other joint keep their values. Each step is the
differential-IK objective of :mod:`mbctl.control.ik.diff_ik` restricted to S, without inequality
limits, solved in closed form (Levenberg-Marquardt)::

    dq_S = argmin_x |W_S x - r|^2 + (damping + sum_i mu_i) |x|^2
         = (W_S^T W_S + (damping + sum_i mu_i) I)^-1 W_S^T r

    W = [diag(cost_i) J_i]_i,  r = [-gain_i diag(cost_i) e_i]_i,  mu_i = lm_damping_i |r_i|^2

and ``q <- pin.integrate(q, dq)`` with ``dq`` zero outside S, then the chain's 1-dof joints
clipped into their position limits (a projected step: a target that needs a joint beyond its
limit stalls there). With gain 1 and no damping this is Newton's method on the tasks' errors; the
damping bounds the step where ``W_S`` is singular (a straight knee) or the target is out of reach,
and vanishes at a solution (``r = 0``). The steps run in the one IK loop
(:func:`mbctl.control.ik.loop.iterate`): converged by the one rule
(:func:`mbctl.control.tasks.residuals.converged`), stalled when the step vanishes short of it.

For a chain of ``n = k`` dofs (a 6-dof leg under a 6-dof foot pose) the solution is unique near
the start; a longer chain takes the least-norm step.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.loop import IKResult, iterate
from mbctl.control.tasks.base import Task
from mbctl.control.tasks.com import ComTask
from mbctl.control.tasks.residuals import TaskResidual, Tolerance
from mbctl.control.tasks.stack import TaskStack
from mbctl.control.tasks.state import KinematicState
from mbctl.exceptions import unknown_name_message

__all__ = ["ChainIK", "chain_joints"]


def chain_joints(model: pin.Model, frame: str) -> tuple[str, ...]:
    """The joints that move ``frame`` relative to the floating base, root first (a leg under a foot).

    Every joint on the path from the model's root to the frame's parent joint, the root's free
    flyer excepted (it is the base the chain hangs from).

    Args:
        model: Pinocchio model.
        frame: A Pinocchio frame (a MuJoCo site or body).

    Raises:
        IKSetupError: No such frame (the message lists close names), or a frame on the base itself.
    """
    if not model.existFrame(frame):
        raise IKSetupError(unknown_name_message("frame", frame, [f.name for f in model.frames]))
    parent = model.frames[model.getFrameId(frame)].parentJoint
    joints = tuple(model.names[j] for j in model.supports[parent]
                   if j > 0 and model.joints[j].shortname() != "JointModelFreeFlyer")
    if not joints:
        raise IKSetupError(f"frame {frame!r} is on the base (joint {model.names[parent]!r}): no chain "
                           "moves it; name a frame on a limb")
    return joints


class ChainIK:
    """Damped least squares for ``tasks`` moving only ``joints``, within their limits (module docstring).

    An :class:`~mbctl.control.ik.loop.IKStepper`; :meth:`solve` runs it in the one IK loop.

    Attributes:
        model: Pinocchio model.
        tasks: The tasks (set their targets before solving).
        joints: The joints that move, model order.
        idx_q: Their configuration indices (read-only).
        idx_v: Their tangent indices S (read-only).
        damping: Levenberg-Marquardt term added to the normal matrix's diagonal [cost].
        state: Kinematic state at the last ``update``.
    """

    def __init__(self, model: pin.Model, tasks: Sequence[Task], joints: Sequence[str], damping: float = 1e-6):
        """Build the stepper.

        Args:
            model: Pinocchio model.
            tasks: Tasks (non-empty); regularisers are allowed (they act on S only).
            joints: Names of the joints that move (any order; each once).
            damping: Levenberg-Marquardt damping (> 0) [cost], e.g. [cost] ~ [1/m^2] for a pose task
                of unit cost: the step shrinks where a singular value of ``W_S`` falls near its root.

        Raises:
            IKSetupError: No tasks, no or repeated joints, an unknown joint (the message lists the
                model's joints), or a damping that is not a positive finite number.
        """
        if not tasks:
            raise IKSetupError("ChainIK needs at least one task.")
        if not (np.isfinite(damping) and damping > 0.0):
            raise IKSetupError(f"damping must be > 0 [cost]; got {damping!r}")
        names = list(model.names)
        if not joints or len(set(joints)) != len(joints):
            raise IKSetupError(f"ChainIK needs distinct joint names; got {list(joints)!r}")
        unknown = [j for j in joints if j not in names]
        if unknown:
            raise IKSetupError(unknown_name_message("joint", unknown[0], names[1:]))
        ids = sorted(names.index(j) for j in joints)
        self.model = model
        self.tasks = tuple(tasks)
        self.joints = tuple(names[j] for j in ids)
        self.idx_q = np.concatenate([np.arange(model.idx_qs[j], model.idx_qs[j] + model.nqs[j]) for j in ids])
        self.idx_v = np.concatenate([np.arange(model.idx_vs[j], model.idx_vs[j] + model.nvs[j]) for j in ids])
        for arr in (self.idx_q, self.idx_v):
            arr.setflags(write=False)
        self.damping = float(damping)
        self.state = KinematicState(model, with_com=any(isinstance(t, ComTask) for t in self.tasks))
        self._stack = TaskStack(model.nv, self.tasks)
        n = len(self.idx_v)
        # the chain's 1-dof joints with finite position limits [rad or m]: each step is clipped into them
        limited = [(model.idx_qs[j], model.lowerPositionLimit[model.idx_qs[j]],
                    model.upperPositionLimit[model.idx_qs[j]]) for j in ids if model.nqs[j] == 1]
        limited = [(i, lo, hi) for i, lo, hi in limited if np.isfinite(lo) and np.isfinite(hi)]
        self._limited_q = np.array([i for i, _, _ in limited], dtype=int)
        self._q_min = np.array([lo for _, lo, _ in limited])
        self._q_max = np.array([hi for _, _, hi in limited])
        self._H = np.zeros((model.nv, model.nv))
        self._c = np.zeros(model.nv)
        self._diag = np.arange(n)
        self._dq = np.zeros(model.nv)

    # ------------------------------------------------------------------ IKStepper
    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""
        return np.array(self.state.q)

    def update(self, q: npt.ArrayLike) -> None:
        """Move to configuration ``q`` (nq,).

        Raises:
            TaskSetupError: ``q`` has the wrong shape or non-finite entries.
        """
        self.state.update(q)

    def task_residuals(self) -> dict[str, TaskResidual]:
        """Every task's residual at the current configuration, by task name."""
        return {t.name: t.residual(self.state) for t in self.tasks}

    @property
    def levels(self) -> tuple[tuple[str, ...], ...]:
        """One level: the tasks are weighed against each other."""
        return (tuple(t.name for t in self.tasks),)

    def advance(self) -> float:
        """One damped least-squares step of the chain, clipped into its limits; ``|dq|_inf`` [rad or m].

        Raises:
            TaskSetupError: A task without a target.
        """
        H, c = self._H, self._c
        mu = self._stack.velocity_objective(self.state, H, c)  # H = W^T W, c = -W^T r over every dof
        S = self.idx_v
        H_S = H[np.ix_(S, S)]
        H_S[self._diag, self._diag] += self.damping + mu
        dq = self._dq
        dq[S] = np.linalg.solve(H_S, -c[S])
        q = self.state.q
        q_next = pin.integrate(self.model, q, dq)
        lim = self._limited_q
        q_next[lim] = np.clip(q_next[lim], self._q_min, self._q_max)
        step = pin.difference(self.model, q, q_next)[S]  # the step taken, after the limits
        self.state.update(q_next)
        return float(np.max(np.abs(step)))

    # ------------------------------------------------------------------ loop
    def solve(self, q0: npt.ArrayLike, tolerance: Tolerance | None = None, max_iters: int = 20,
              step_tol: float = 1e-9) -> IKResult:
        """Iterate from ``q0`` (nq,) until every target task meets ``tolerance``, moving only the chain.

        Args:
            q0: Start configuration (nq,), Pinocchio convention; everything off the chain keeps its value.
            tolerance: Position [m] and orientation [rad] tolerances (default 1 mm, 0.01 rad).
            max_iters: Maximum number of steps (>= 1).
            step_tol: Stop when a step's inf-norm falls below this [rad or m].

        Returns:
            The loop's result: ``converged`` False (and ``stalled`` when the step vanished) for a
            target the chain cannot reach within its joint limits; ``q`` is then the damped closest
            pose found, inside the limits.

        Raises:
            IKSetupError: ``max_iters`` < 1 or a negative ``step_tol``.
            TaskSetupError: A task without a target, or a bad ``q0``.
        """
        return iterate(self, q0, tolerance or Tolerance(), max_iters, step_tol)
