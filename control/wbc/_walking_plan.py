"""The walk's DCM plan through its footsteps (:class:`WalkPlans`), reused while its inputs stay.

The plan of :class:`~mbctl.control.wbc.walking.WalkingController` runs through the swing footstep (or,
in double support and at the start, the gait's next one) and ``preview_steps`` footsteps planned on
from it (:class:`~mbctl.planners.footsteps.FootstepPlanner`), then stops between the last two. Its
inputs are the gait's (:meth:`~mbctl.control.wbc.gait.Gait.plan_start`: the footsteps, the VRPs in
force, the first switch, the start's DCM) and the footsteps' command; most cycles plan through the
same inputs as the cycle before (double support, a swing footstep no longer moving, between footstep
plannings), so a plan is built once per inputs and reused.
"""

from __future__ import annotations

import math

from mbctl.control.wbc.gait import Gait
from mbctl.control.wbc.walking_config import WalkingConfig
from mbctl.planners.dcm import DcmPlan
from mbctl.planners.footsteps import Footstep, FootstepPlanner, VelocityCommand

#: Where each double support's DCM switch sits in it [-] (0.5: centred).
DS_ALPHA = 0.5

#: DCM plans kept for reuse, by their inputs (the last few cycles' distinct plans).
PLANS_KEPT = 4

#: A plan and the footsteps it runs through (the swing foot's first).
Planned = tuple[DcmPlan, list[Footstep]]


def _step_key(step: Footstep | None) -> tuple | None:
    """A footstep's values, as a key (exact: equal keys plan equal footsteps)."""
    return None if step is None else (step.foot, step.side, *step.position.tolist(), step.yaw_rad)


class WalkPlans:
    """The DCM plans of one walk, each built once per inputs (see the module docstring).

    Args:
        planner: The footstep planner.
        config: The walking options (timing, ``preview_steps``).
        omega_rad_s: ``sqrt(g / z_c)`` [rad/s].
    """

    def __init__(self, planner: FootstepPlanner, config: WalkingConfig, omega_rad_s: float):
        self.planner, self.config, self.omega = planner, config, omega_rad_s
        self.reset()

    def reset(self) -> None:
        """Forget every plan (a new walk)."""
        self._memo: tuple[tuple, Planned] | None = None
        self._plans: dict[tuple, Planned] = {}
        self._by_state: tuple[tuple, Planned] | None = None

    def plan(self, gait: Gait, t: float, command: VelocityCommand,
             swing_step: Footstep | None = None) -> Planned:
        """The DCM plan from ``t`` through the swing footstep (or ``swing_step``) and the preview footsteps.

        Args:
            gait: The walk's gait.
            t: Now [s].
            command: The footsteps' command.
            swing_step: A footstep to plan through instead of the gait's swing footstep.
        """
        cfg = self.config
        # the gait's footsteps (its revision), the first switch and the command give the plan's inputs: a
        # cycle after one that looked the plan up by them reuses it (not a cycle that planned the swing
        # footstep: its plan may be the one through the nominal footstep, below)
        memo = self._memo
        if swing_step is None and (memo is None or memo[0][0] != t):
            state = (gait.revision, gait.first_switch_s(t, DS_ALPHA), command)
            if self._by_state is not None and self._by_state[0] == state:
                return self._by_state[1]
        first, vrps, t1, stance, initial = gait.plan_start(t, DS_ALPHA, command)
        if swing_step is not None:
            first = stance = swing_step
        # a cycle that moves the swing footstep plans twice, through the nominal footstep and then
        # through the one it swings to: the same plan when the adaptation kept the nominal one (the
        # swing path keeps its yaw unwrapped and rounds: equal to 1e-12 m and rad counts as the same)
        first_key = _step_key(first)
        key = (t, command, None if first_key is None else (  # (foot, side, x, y, z, yaw)
            round(first_key[2], 12), round(first_key[3], 12),
            round(math.remainder(first_key[5], 2.0 * math.pi), 12)))
        if memo is not None and memo[0] == key:
            return memo[1]
        # the plan depends on these only (on t through t1): a cycle planning through the same footsteps
        # at the same command as an earlier one (double support, a swing footstep no longer moving) reuses it
        vrp_list = [v.tolist() for v in vrps]  # (x, y) [m] pairs
        inputs = (first_key, first_key if stance is first else _step_key(stance),
                  tuple(map(tuple, vrp_list)), t1,
                  None if initial is None else (initial[0], *initial[1].tolist(), *initial[2].tolist()),
                  command)
        plan = self._plans.get(inputs)
        if plan is None:
            steps = [first] if first is not None else []
            steps += self.planner.plan(stance, command, cfg.preview_steps)
            vrp_list += [gait.vrp(s).tolist() for s in steps]
            (lx, ly), (bx, by) = vrp_list[-1], vrp_list[-2] if len(steps) > 1 else gait.vrp(stance).tolist()
            vrp_list.append([0.5 * (lx + bx), 0.5 * (ly + by)])  # the stop: between the last two footsteps
            switches = [t1 + cfg.timing.step_s * k for k in range(len(vrp_list) - 1)]  # (as t1 + T arange(n))
            plan = DcmPlan.of_lists(self.omega, vrp_list, switches, cfg.timing.double_support_s, DS_ALPHA,
                                    initial), steps
            if len(self._plans) >= PLANS_KEPT:
                del self._plans[next(iter(self._plans))]  # the oldest
            self._plans[inputs] = plan
        self._memo = (key, plan)
        if swing_step is None:
            self._by_state = ((gait.revision, t1, command), plan)
        return plan
