"""Facts about the Menagerie Unitree G1, in one place: names, limbs, the standing start, what "fell" means.

Nothing in control/ names the G1: generic code (whole-body IK, the whole-body controller) takes
frame names as parameters, and the jobs fill them from here, only for the robot that IS the
Menagerie G1 (:func:`is_menagerie_g1`: loaded by the registry name "g1", told apart by its recorded
origin, never by the file stem).

Palm sites. The Menagerie G1 has no palm sites, so the jobs add them at load time with
:func:`mbctl.robots.edits.add_site` (recorded in ``robot.source.edits``): ``left_palm`` on body
``left_wrist_yaw_link`` and ``right_palm`` on ``right_wrist_yaw_link``, at
:data:`PALM_OFFSET_IN_WRIST_YAW_M` = (0.08, 0, 0) m in the body frame, identity orientation. The
rubber hand mesh starts at x = 0.0415 m on that link and the link's CoM (hand included) is at
x = 0.0708 m, so 0.08 m is about mid-palm along the hand's long axis.

Falling. The G1 has fallen when its pelvis is below :data:`FALL_HEIGHT_M` or when a body other than
its feet touches the floor (:data:`G1_FALL`); the plant measures both
(:class:`mbctl.sim.monitor.PlantMonitor`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.robots.edits import add_contact_sensors, add_floor_sensors, add_site, position_to_motor
from mbctl.robots.interface import ImuSpec
from mbctl.robots.model_pair import Robot

#: Registry name of the Menagerie G1 (``mbctl.robots.registry.KNOWN_ROBOTS``).
G1_NAME = "g1"

#: Start of ``ModelSource.origin`` for the registry's G1 (``robots.registry._locate_g1``).
G1_ORIGIN_PREFIX = "MuJoCo Menagerie unitree_g1"

#: Keyframe the G1 jobs start from (standing pose).
KEYFRAME = "stand"

#: Palm site offset [m] in each wrist-yaw link frame (see the module docstring for the choice).
PALM_OFFSET_IN_WRIST_YAW_M = (0.08, 0.0, 0.0)

#: Palm site name -> the body it is attached to.
PALM_SITES = {"left_palm": "left_wrist_yaw_link", "right_palm": "right_wrist_yaw_link"}

#: Foot sites (held by the whole-body IK; the whole-body controller's contact frames).
FEET = ("left_foot", "right_foot")

#: The bodies that carry the foot sites and touch the ground.
FOOT_BODIES = ("left_ankle_roll_link", "right_ankle_roll_link")

#: The pelvis IMU (the one the G1's low-level LowState reports): its site and its two sensors.
G1_IMU = ImuSpec("imu_in_pelvis", "imu-pelvis-angular-velocity", "imu-pelvis-linear-acceleration")

#: Floating-base body.
PELVIS = "pelvis"

#: Upper-body link whose orientation the whole-body controller holds.
TORSO = "torso_link"

#: Words that put a joint in a leg (leg joints carry the body) or an arm.
LEG_WORDS = ("hip", "knee", "ankle")
ARM_WORDS = ("shoulder", "elbow", "wrist")

#: Forearm and hand bodies of each arm (elbow link = forearm; the wrist links carry the hand).
FOREARM_HAND = {side: (f"{side}_elbow_link", f"{side}_wrist_roll_link", f"{side}_wrist_pitch_link",
                       f"{side}_wrist_yaw_link") for side in ("left", "right")}

#: The trunk (torso and pelvis) and the thighs (hip roll and hip yaw links), which hands reach.
TRUNK = ("torso_link", "pelvis")
THIGHS = ("left_hip_roll_link", "left_hip_yaw_link", "right_hip_roll_link", "right_hip_yaw_link")

#: The G1's default self-collision set, by body name (``mbctl.robots.collision.CollisionPair``
#: sides): the forearms and hands against each other, against the trunk and against the thighs;
#: foot against foot. Each name stands for the body's collision geoms.
SELF_COLLISION_PAIRS: tuple[tuple[tuple[str, ...], tuple[str, ...]], ...] = (
    (FOREARM_HAND["left"], FOREARM_HAND["right"]),
    ((*FOREARM_HAND["left"], *FOREARM_HAND["right"]), (*TRUNK, *THIGHS)),
    ((FOOT_BODIES[0],), (FOOT_BODIES[1],)),
)

#: Pelvis height [m] below which the G1 has fallen.
FALL_HEIGHT_M = 0.5

#: Leg joints of the crouched start [rad]: the keyframe's straight knees are a singularity of the
#: CoM height (its Jacobian row vanishes), so whole-body control starts with bent knees.
CROUCH_RAD = {"hip_pitch": -0.3, "knee": 0.6, "ankle_pitch": -0.3}


@dataclass(frozen=True)
class FallRule:
    """When a robot on the floor has fallen: its base too low, or a non-supporting body on the floor.

    Attributes:
        base_min_z_m: Base (free-joint) height [m] below which it has fallen.
        support_bodies: Bodies allowed to touch the floor (the feet).
        base_name: What the messages call the base (the G1's is its pelvis).
    """

    base_min_z_m: float
    support_bodies: tuple[str, ...]
    base_name: str = "base"

    def reason(self, base_z_m: float, floor_bodies: Sequence[str]) -> str | None:
        """Why the robot has fallen (None: it has not).

        Args:
            base_z_m: Height of the floating base [m].
            floor_bodies: Names of the robot's bodies touching the floor.
        """
        if base_z_m < self.base_min_z_m:
            return f"{self.base_name} at {base_z_m:.3f} m (below {self.base_min_z_m:g} m)"
        support = self.support_bodies
        for body in floor_bodies:  # checked every control period: no set built while only feet touch
            if body not in support:
                others = sorted({b for b in floor_bodies if b not in support})
                return f"{', '.join(others)} touched the floor"
        return None


#: The G1's fall rule.
G1_FALL = FallRule(FALL_HEIGHT_M, FOOT_BODIES, "pelvis")


def is_menagerie_g1(robot: Robot) -> bool:
    """True when ``robot`` is the registry's Menagerie G1 (a user file named g1.xml is not).

    Args:
        robot: Any loaded model pair (edits such as palm sites keep the identity).
    """
    return robot.source.name == G1_NAME and robot.source.origin.startswith(G1_ORIGIN_PREFIX)


def with_palm_sites(robot: Robot) -> Robot:
    """A copy of the G1 with the ``left_palm``/``right_palm`` sites in both engines (idempotent).

    Raises:
        UnknownNameError: The robot lacks a wrist-yaw body (not a G1).
    """
    for site, body in PALM_SITES.items():
        if site not in robot.sites:
            robot = add_site(robot, site, body, PALM_OFFSET_IN_WRIST_YAW_M)
    return robot


def whole_body_g1(robot: Robot) -> Robot:
    """The G1 as the whole-body jobs run it (a copy; idempotent).

    Torque motors (force ranges kept), the palm sites, a net-force contact sensor on each foot and
    the floor's contact counts, the robot's and each foot's (the plant monitor reads the feet's
    forces and the bodies on the floor from MuJoCo).
    """
    return add_floor_sensors(add_contact_sensors(position_to_motor(with_palm_sites(robot)), FOOT_BODIES),
                             FOOT_BODIES)


def limb_of(joint: str) -> str:
    """The limb of a G1 joint: "left leg", "right arm", "waist" (else its first word)."""
    side = next((s for s in ("left", "right") if joint.startswith(f"{s}_")), None)
    if any(w in joint for w in LEG_WORDS):
        part = "leg"
    elif any(w in joint for w in ARM_WORDS):
        part = "arm"
    else:
        part = joint.removeprefix(f"{side}_").split("_")[0] if side else joint.split("_")[0]
    return f"{side} {part}" if side else part


def joint_role(joint: str) -> str:
    """A joint's name within its limb: ``left_knee_joint`` -> ``knee``, ``waist_yaw_joint`` -> ``waist_yaw``.

    Args:
        joint: The joint name.
    """
    for side in ("left_", "right_"):
        joint = joint.removeprefix(side)
    return joint.removesuffix("_joint")


def crouched_start(robot: Robot) -> np.ndarray:
    """The ``stand`` keyframe with bent knees (:data:`CROUCH_RAD`), feet flat where they were (nq,).

    The base moves down and back by the feet's displacement, so the soles keep their keyframe
    pose (hip + knee + ankle pitch = 0 keeps them flat).
    """
    model = robot.pin_model
    data = model.createData()
    q = robot.keyframe_q(KEYFRAME).copy()
    for side in ("left", "right"):
        for joint, value in CROUCH_RAD.items():
            q[robot.joint(f"{side}_{joint}_joint").idx_q] = value
    feet = [model.getFrameId(f) for f in FEET]
    pin.framesForwardKinematics(model, data, robot.keyframe_q(KEYFRAME))
    before = np.mean([data.oMf[f].translation for f in feet], axis=0)
    pin.framesForwardKinematics(model, data, q)
    after = np.mean([data.oMf[f].translation for f in feet], axis=0)
    q[:3] += before - after
    return q
