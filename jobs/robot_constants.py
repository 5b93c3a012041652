"""Names and numbers tied to the Menagerie Unitree G1, in one place (nothing in control/ names them).

The generic whole-body IK (``mbctl.control.ik.backends``) takes frame names as parameters; the jobs
fill them from here, and only for the robot that IS the Menagerie G1 (``is_menagerie_g1``: loaded
by the registry name "g1", told apart by its recorded origin, never by the file stem).

Palm sites. The Menagerie G1 has no palm sites, so the jobs add them at load time with
``mbctl.robots.edits.add_site`` (recorded in ``robot.source.edits``): ``left_palm`` on body
``left_wrist_yaw_link`` and ``right_palm`` on ``right_wrist_yaw_link``, at
``PALM_OFFSET_IN_WRIST_YAW_M`` = (0.08, 0, 0) m in the body frame, identity orientation. The rubber
hand mesh starts at x = 0.0415 m on that link and the link's CoM (hand included) is at
x = 0.0708 m, so 0.08 m is about mid-palm along the hand's long axis.
"""

from __future__ import annotations

from mbctl.control.ik.backends import WholeBodyIKConfig
from mbctl.robots.edits import add_site
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

#: Foot sites (held at their start pose by the whole-body IK).
FEET = ("left_foot", "right_foot")

#: Floating-base body (its orientation is held by the whole-body IK).
PELVIS = "pelvis"


def is_menagerie_g1(robot: Robot) -> bool:
    """True when ``robot`` is the registry's Menagerie G1 (a user file named g1.xml is not).

    Args:
        robot: Any loaded model pair (edits such as palm sites keep the identity).
    """
    return robot.source.name == G1_NAME and robot.source.origin.startswith(G1_ORIGIN_PREFIX)


def g1_whole_body_config(**weights: float) -> WholeBodyIKConfig:
    """The G1 whole-body task set (mink's humanoid example): feet held, palm targets, CoM, pelvis.

    Args:
        **weights: Overrides of ``WholeBodyIKConfig``'s weights and limits.
    """
    return WholeBodyIKConfig(held_frames=FEET, target_frames=tuple(PALM_SITES), base_frame=PELVIS,
                             com=True, **weights)  # type: ignore[arg-type]


def with_palm_sites(robot: Robot) -> Robot:
    """A copy of the G1 with the ``left_palm``/``right_palm`` sites in both engines (idempotent).

    Raises:
        UnknownNameError: The robot lacks a wrist-yaw body (not a G1).
    """
    for site, body in PALM_SITES.items():
        if site not in robot.sites:
            robot = add_site(robot, site, body, PALM_OFFSET_IN_WRIST_YAW_M)
    return robot
