"""Write identified parameters into the robot's MJCF, so both engines carry them.

Each identified body's ``<inertial>`` (mass, CoM, principal moments and axes) is set with MjSpec;
friction goes into the joint's ``damping`` (viscous) and ``frictionloss`` (Coulomb), armature into
``armature``. The result is the robot's own MJCF with the values replaced: MuJoCo reads it, and the
Pinocchio model is built from it as for any robot (``load_robot(path)``), so the cross-check holds
for the identified model as it does for the nominal one.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mbctl.robots.edits import set_inertial, standalone_xml
from mbctl.robots.identification.exceptions import InconsistentParameters
from mbctl.robots.identification.inertial import consistency_problems, to_inertial
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.model_pair import Robot

#: Relative margin kept on the triangle inequality of the written principal moments: MuJoCo writes
#: 6 significant digits, and an estimate on the boundary must not round to the wrong side of it.
TRIANGLE_MARGIN = 1e-5


def identified_spec(robot: Robot, params: ParameterSet, theta: np.ndarray) -> mujoco.MjSpec:
    """A copy of ``robot``'s MjSpec with ``theta`` written in.

    Raises:
        InconsistentParameters: A body's parameters are not physically consistent (never written).
    """
    spec = robot.mj_spec.copy()
    for b in params.bodies:
        pi = theta[b.columns]
        problems = consistency_problems(pi)
        if problems:
            raise InconsistentParameters(f"body {b.name!r}: {'; '.join(problems)}; not written")
        mass, com, inertia = to_inertial(pi)
        set_inertial(spec.body(b.name), mass, com, _off_the_boundary(inertia))
    for jb in params.joints:
        joint = spec.joint(jb.name)
        if jb.viscous is not None and jb.coulomb is not None:
            damping = np.array(joint.damping, dtype=float)  # MuJoCo 4: [linear, higher-order terms]
            damping[0] = float(theta[jb.viscous])
            joint.damping = damping
            joint.frictionloss = float(theta[jb.coulomb])
        if jb.armature is not None:
            joint.armature = float(theta[jb.armature])
    return spec


def identified_xml(robot: Robot, params: ParameterSet, theta: np.ndarray) -> str:
    """The identified MJCF as text, loadable from any folder (mesh and texture paths absolute).

    Args:
        robot: The nominal robot.
        params: The parameter set ``theta`` belongs to.
        theta: The identified parameters (n,).
    """
    return standalone_xml(robot, identified_spec(robot, params, theta))


def _off_the_boundary(inertia_com: np.ndarray) -> np.ndarray:
    """``inertia_com`` kept off the triangle boundary by :data:`TRIANGLE_MARGIN`.

    The smallest principal moment is raised just enough that ``a + b >= c (1 + margin)``
    (unchanged when that already holds). Raising the smallest keeps the moments' order, so the
    largest stays the one the inequality bounds: a body at the boundary is a thin rod (``a`` near
    0, ``b`` near ``c``), where raising ``b`` would overtake ``c``.
    """
    moments, axes = np.linalg.eigh(0.5 * (inertia_com + inertia_com.T))
    a, b, c = moments
    short = c * (1.0 + TRIANGLE_MARGIN) - a - b
    if short <= 0:
        return inertia_com
    if a + short <= b:
        moments[0] += short
    else:  # a and b are close: raise both, still below the (raised) bound
        moments[:2] = 0.5 * c * (1.0 + TRIANGLE_MARGIN) + 0.5 * (moments[:2] - 0.5 * (a + b))
        moments[2] = max(c, moments[1])
    return (axes * moments) @ axes.T
