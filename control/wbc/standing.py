"""A robot standing on its feet: the whole-body controller with the standing task set, for any biped.

The task set (weights and PD gains: cost, omega [rad/s], zeta): CoM (10, 10, 1), base orientation
(5, 10, 1), torso orientation (2, 10, 1), posture of the joints (0.05, 10, 1) and angular-momentum
damping (0.2, 4, 1); every foot in contact. Frame names are parameters: nothing here names a
particular robot (robot facts live in robots/, e.g. :mod:`mbctl.robots.g1`).

:class:`Scheduled` runs such a controller in the control loop with task targets that follow a
function of time (a scenario: squat, shift the weight, lift a foot).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import pinocchio as pin

from mbctl.control.tasks.angular_momentum import AngularMomentumTask
from mbctl.control.tasks.base import AccelerationGains, Task
from mbctl.control.tasks.com import ComTask
from mbctl.control.tasks.frame_orientation import FrameOrientationTask
from mbctl.control.tasks.posture import PostureTask
from mbctl.control.wbc.config import WBCConfig
from mbctl.control.wbc.contacts import FootContact, foot_contact_from_model
from mbctl.control.wbc.controller import WholeBodyController
from mbctl.robots.commands import Command
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


@dataclass
class Standing:
    """The whole-body controller and its standing tasks (targets are set on the tasks).

    Attributes:
        controller: The whole-body QP.
        com: Centre-of-mass task.
        base: Base (pelvis) orientation task.
        torso: Torso orientation task (None without a torso frame).
        posture: Joint posture regulariser.
        momentum: Angular-momentum damping.
        extra: Tasks a scenario adds (swing foot, hands), by name.
    """

    controller: WholeBodyController
    com: ComTask
    base: FrameOrientationTask
    torso: FrameOrientationTask | None
    posture: PostureTask
    momentum: AngularMomentumTask
    extra: dict[str, Task] = field(default_factory=dict)

    def hold(self, state: RobotState) -> None:
        """Every foot in contact where it is, and every task's target at ``state``'s values, at rest."""
        self.controller.reset_contacts(state)
        s = self.controller.state
        self.com.set_target(s.com().copy())
        self.base.set_target(pin.SE3(s.frame_pose(self.base.frame_id)))
        if self.torso is not None:
            self.torso.set_target(pin.SE3(s.frame_pose(self.torso.frame_id)))
        self.posture.set_target(state.q)


def standing_controller(robot: Robot, feet: Sequence[str], base_frame: str, torso_frame: str | None = None,
                        pin_model: pin.Model | None = None, config: WBCConfig | None = None,
                        contacts: Sequence[FootContact] | None = None) -> Standing:
    """The whole-body controller on ``robot`` (torque actuators) with the standing task set.

    Args:
        robot: A floating-base robot whose actuators are torque motors.
        feet: Foot frames (sites or bodies); their contact points come from the foot bodies'
            collision geoms (:func:`~mbctl.control.wbc.contacts.foot_contact_from_model`).
        base_frame: The floating base's frame (its orientation is held).
        torso_frame: An upper-body frame whose orientation is held too, or None.
        pin_model: The controller's analytic model (default ``robot.pin_model``).
        config: QP options.
        contacts: The feet's contact points, if not from the foot bodies' geoms (e.g. a finer grid
            over each sole); one per foot frame.

    Raises:
        WBCSetupError: A foot without a colliding sphere or box geom, or an unknown frame.
        UnknownNameError: An unknown base or torso frame.
    """
    if contacts is None:
        contacts = [foot_contact_from_model(robot, f) for f in feet]
    ctrl = WholeBodyController(robot, contacts, config, pin_model=pin_model)
    m = ctrl.model
    torso = None
    if torso_frame is not None:
        torso = FrameOrientationTask(torso_frame, m, cost=2.0, servo=AccelerationGains(10.0, 1.0))
    standing = Standing(
        ctrl,
        com=ComTask(cost=10.0, servo=AccelerationGains(10.0, 1.0)),
        base=FrameOrientationTask(base_frame, m, cost=5.0, servo=AccelerationGains(10.0, 1.0)),
        torso=torso,
        posture=PostureTask(m, cost=0.05, servo=AccelerationGains(10.0, 1.0)),
        momentum=AngularMomentumTask(cost=0.2, servo=AccelerationGains(4.0, 1.0)),
    )
    for task in (standing.com, standing.base, standing.torso, standing.posture, standing.momentum):
        if task is not None:
            ctrl.add_task(task)
    return standing


class Scheduled:
    """A whole-body controller whose targets follow ``schedule(t, state)`` (t [s] since the first state).

    A :class:`~mbctl.control.controller.Controller` for :func:`mbctl.control.loop.run` (pass
    ``reference=None``): each ``compute`` first calls ``schedule(state.time_s - t_start, state)``,
    which sets task targets (and may add tasks, release or put down feet; the measured state is
    there for schedules that react to it, e.g. a swing leg placed from the current base), then solves.

    Args:
        controller: The whole-body controller.
        schedule: Sets the targets for a time [s] since the start, given the state being controlled.
    """

    reference_type = None

    def __init__(self, controller: WholeBodyController, schedule: Callable[[float, RobotState], None]):
        self.controller = controller
        self.schedule = schedule
        self._t_start: float | None = None

    def reset(self) -> None:
        """Restart the schedule's clock at the next state."""
        self._t_start = None
        self.controller.reset()

    def compute(self, state: RobotState, reference: object = None) -> Command:
        """Targets at the schedule's time, then the whole-body torques for ``state``."""
        if self._t_start is None:
            self._t_start = state.time_s
        self.schedule(state.time_s - self._t_start, state)
        return self.controller.compute(state)
