"""A small biped built in code, so the whole-body controller is tested without the G1.

Floating pelvis, a waist yaw, two 6-dof legs (hip yaw, roll and pitch in one body, knee, ankle
pitch and roll in one body), four sole spheres per foot, torque motors; 23 kg. ``tiny_biped_reordered``
is the same robot with its actuators declared in another order (the controller then indexes its
torque rows with index arrays instead of slices).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import Robot, load_robot


def _leg(side: str, y: float) -> str:
    spheres = "\n".join(
        f'<geom type="sphere" size="0.012" pos="{x} {dy} -0.038" contype="1" conaffinity="1"/>'
        for x in (0.09, -0.05) for dy in (0.035, -0.035))
    return f"""
      <body name="{side}_thigh" pos="0 {y} -0.05">
        <joint name="{side}_hip_yaw" axis="0 0 1" range="-0.8 0.8"/>
        <joint name="{side}_hip_roll" axis="1 0 0" range="-0.6 0.6"/>
        <joint name="{side}_hip_pitch" axis="0 1 0" range="-1.6 1.0"/>
        <inertial pos="0 0 -0.12" mass="2.5" diaginertia="0.03 0.03 0.004"/>
        <body name="{side}_shin" pos="0 0 -0.26">
          <joint name="{side}_knee" axis="0 1 0" range="0 2.3"/>
          <inertial pos="0 0 -0.12" mass="1.8" diaginertia="0.02 0.02 0.003"/>
          <body name="{side}_foot" pos="0 0 -0.26">
            <joint name="{side}_ankle_pitch" axis="0 1 0" range="-1 1"/>
            <joint name="{side}_ankle_roll" axis="1 0 0" range="-0.6 0.6"/>
            <inertial pos="0.02 0 -0.02" mass="0.6" diaginertia="0.002 0.003 0.003"/>
            <site name="{side}_sole" pos="0 0 -0.05"/>
            {spheres}
          </body>
        </body>
      </body>"""


JOINTS = ["waist", *[f"{s}_{j}" for s in ("l", "r") for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee",
                                                                    "ankle_pitch", "ankle_roll")]]


def biped_xml(actuator_order: list[str]) -> str:
    """The biped's MJCF with its motors declared in ``actuator_order``."""
    motors = "\n".join(f'<motor name="m_{j}" joint="{j}" ctrlrange="-120 120"/>' for j in actuator_order)
    return f"""
<mujoco model="tiny_biped">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <default><joint damping="0.05" armature="0.01"/><geom contype="0" conaffinity="0" friction="0.8"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" contype="1" conaffinity="1"/>
    <body name="pelvis" pos="0 0 0.66">
      <freejoint name="root"/>
      <inertial pos="0 0 0.02" mass="8" diaginertia="0.08 0.06 0.06"/>
      <body name="torso" pos="0 0 0.08">
        <joint name="waist" axis="0 0 1" range="-1 1"/>
        <inertial pos="0 0 0.15" mass="5" diaginertia="0.08 0.07 0.04"/>
        <site name="chest" pos="0.05 0 0.25"/>
      </body>
      {_leg("l", 0.1)}
      {_leg("r", -0.1)}
    </body>
  </worldbody>
  <actuator>{motors}</actuator>
</mujoco>
"""


CROUCH = {"hip_pitch": -0.35, "knee": 0.7, "ankle_pitch": -0.35}


def crouch(robot: Robot) -> np.ndarray:
    """Knees bent, soles flat on the floor (z = 0 at the spheres' bottoms)."""
    q = robot.neutral_q()
    for side in ("l", "r"):
        for joint, value in CROUCH.items():
            q[robot.joint(f"{side}_{joint}").idx_q] = value
    model = robot.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    sole_z = data.oMf[model.getFrameId("l_sole")].translation[2]
    q[2] -= sole_z - (0.05 - 0.038 - 0.012)  # the spheres' bottoms 0 mm above the floor
    return q


@pytest.fixture(scope="session", name="crouch")
def crouch_fixture():
    """``crouch(robot) -> q``: the biped's standing start (pytest imports no conftest by name)."""
    return crouch


@pytest.fixture(scope="session")
def tiny_biped(tmp_path_factory) -> Robot:
    path = tmp_path_factory.mktemp("biped") / "tiny_biped.xml"
    path.write_text(biped_xml(JOINTS))
    return load_robot(path)


@pytest.fixture(scope="session")
def tiny_biped_reordered(tmp_path_factory) -> Robot:
    order = JOINTS[::2] + JOINTS[1::2]  # every other joint first: no contiguous run of dofs
    path = tmp_path_factory.mktemp("biped_reordered") / "tiny_biped.xml"
    path.write_text(biped_xml(order))
    return load_robot(path)
