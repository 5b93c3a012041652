"""The load-time check that a model pair's two engines describe the same mechanism.

Sizes, joint names and order, the robot's total mass, armature, and forward kinematics of every
body and site at the neutral pose and at random configurations (Pinocchio's frames against
MuJoCo's own ``mj_kinematics``). The full dynamics comparison is the cross-check
(``robots/crosscheck``); this one runs on every load.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from mbctl.robots.exceptions import ModelMismatchError
from mbctl.robots.plant_kinematics import PlantKinematics
from mbctl.robots.site_frames import site_frame

if TYPE_CHECKING:
    from mbctl.robots.model_pair import Robot

#: Relative tolerance on total mass and absolute tolerance on armature [kg m^2] in the
#: load-time agreement check: both engines parse the same decimal strings, so anything beyond
#: floating-point round-off is a real difference.
MASS_RTOL = 1e-9
ARMATURE_ATOL = 1e-12


def check_agreement(robot: Robot) -> None:
    """Check both engines describe the same mechanism; ModelMismatchError lists what differs."""
    pm, m = robot.pin_model, robot.mj_model
    problems = []
    nq, nv = robot.converter.nq, robot.converter.nv
    if (pm.nq, pm.nv) != (nq, nv):
        problems.append(f"sizes differ: Pinocchio nq={pm.nq}, nv={pm.nv}; MuJoCo robot nq={nq}, nv={nv}")
    pin_names = list(pm.names)[1:]
    mj_names = list(robot.joints)
    if pin_names != mj_names:
        diff = [
            f"#{i}: {a!r} vs {b!r}"
            for i, (a, b) in enumerate(zip(pin_names, mj_names, strict=False))
            if a != b
        ]
        problems.append(
            f"joint names/order differ (Pinocchio vs MuJoCo): {len(pin_names)} vs "
            f"{len(mj_names)} joints; " + ", ".join(diff[:5])
        )
    pin_mass = sum(inertia.mass for inertia in pm.inertias)
    mj_mass = float(np.sum(m.body_mass[list(robot.robot_body_ids)]))  # the robot's, not the scene's
    if not np.isclose(pin_mass, mj_mass, rtol=MASS_RTOL, atol=0):
        problems.append(f"robot mass differs: Pinocchio {pin_mass:.9g} kg, MuJoCo {mj_mass:.9g} kg")
    if pm.nv == nv:
        mj_arm = m.dof_armature[robot.qvel_index]
        bad = np.flatnonzero(np.abs(np.asarray(pm.armature) - mj_arm) > ARMATURE_ATOL)
        if bad.size:
            problems.append(
                f"armature differs at dofs {bad[:8].tolist()}: Pinocchio "
                f"{np.asarray(pm.armature)[bad[:8]].tolist()}, MuJoCo {mj_arm[bad[:8]].tolist()}"
            )
    if not problems:
        problems += _kinematics_problems(robot)
    if problems:
        raise ModelMismatchError(
            f"Pinocchio model ({robot.source.robot_file}) and MuJoCo model "
            f"({robot.source.scene_file}) of {robot.name!r} disagree: " + "; ".join(problems)
        )


#: Largest FK difference [m, or rotation-matrix entry] the load-time check accepts.
FK_ATOL = 1e-9


def _kinematics_problems(robot: Robot, n_random: int = 2, seed: int = 0) -> list[str]:
    """FK of every body and site, both engines, at the neutral pose and random configurations."""
    pm = robot.pin_model
    data, kinematics = pm.createData(), PlantKinematics(robot=robot)
    lower = np.where(np.isfinite(pm.lowerPositionLimit), pm.lowerPositionLimit, -1.0).clip(-1e3, 1e3)
    upper = np.where(np.isfinite(pm.upperPositionLimit), pm.upperPositionLimit, 1.0).clip(-1e3, 1e3)
    np.random.seed(seed)  # pin.randomConfiguration draws from numpy's global generator
    configurations = [pin.neutral(pm)] + [pin.randomConfiguration(pm, lower, upper) for _ in range(n_random)]
    frames = [("body", name, i, pm.getFrameId(name, pin.FrameType.BODY))
              for name, i in zip(robot.bodies, robot.robot_body_ids, strict=True)]
    frames += [("site", name, i, pm.nframes if fid is None else fid)  # a site's counterpart: site_frame
               for name, i in zip(robot.sites, robot.robot_site_ids, strict=True)
               for fid in (site_frame(pm, name),)]
    missing = [f"{kind} {name!r}" for kind, name, _, fid in frames if fid >= pm.nframes]
    if missing:
        return [f"missing in Pinocchio: {', '.join(missing[:8])}"
                + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")]
    worst: tuple[float, str] = (0.0, "")
    for q in configurations:
        pin.framesForwardKinematics(pm, data, q)
        d = kinematics.at(q)
        for kind, name, i, fid in frames:
            pos, rot = (d.xpos[i], d.xmat[i]) if kind == "body" else (d.site_xpos[i], d.site_xmat[i])
            oMf = data.oMf[fid]
            err = max(float(np.abs(oMf.translation - pos).max()),
                      float(np.abs(oMf.rotation.ravel() - rot).max()))
            if err > worst[0]:
                worst = (err, f"{kind} {name!r}")
    if worst[0] > FK_ATOL:
        return [f"forward kinematics differ by {worst[0]:.3g} (m or rotation entry) at {worst[1]} "
                f"(tolerance {FK_ATOL:g})"]
    return []
