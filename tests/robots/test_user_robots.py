"""Robots users bring, end to end: load (agreement check on), cross-check, IK checked in MuJoCo.

The analytic model is built from MuJoCo's compiled model by default, so the features Pinocchio's
MJCF parser mishandles (a rotated jointless root, several joints in one body, several trees, sites
from default classes or inside frames) load and agree.
"""

from __future__ import annotations

import json
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from mbctl.robots import ModelMismatchError, load_robot
from mbctl.robots.crosscheck import crosscheck

ARM = """
<body name="upper" pos="0 0 0.1">
  <joint name="shoulder" axis="0 1 0" range="-115 115" limited="true"/>
  <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1.2"/>
  <body name="fore" pos="0.3 0 0" euler="0 -40 0">
    <joint name="elbow" axis="0 1 0" range="-140 140" limited="true"/>
    <geom type="box" size="0.12 0.02 0.02" pos="0.12 0 0.01" mass="0.7"/>
    <site name="tool" class="marker"/>
    <frame pos="0.1 0 0.05" euler="0 45 0"><site name="framed" pos="0.05 0 0"/></frame>
  </body>
</body>
"""

DEFAULTS = '<default><default class="marker"><site pos="0.25 0 0"/></default></default>'

ROBOTS = {
    "rotated_root": f"""<mujoco>{DEFAULTS}<worldbody>
      <body name="mount" pos="0.4 -0.2 1.1" euler="30 -20 70">
        <geom type="cylinder" size="0.05 0.05" mass="3"/>{ARM}</body></worldbody>
      <actuator><motor joint="shoulder"/><motor joint="elbow"/></actuator></mujoco>""",
    "mobile_base": f"""<mujoco>{DEFAULTS}<worldbody>
      <body name="base" pos="0 0 0.2">
        <joint name="base_x" type="slide" axis="1 0 0"/><joint name="base_y" type="slide" axis="0 1 0"/>
        <joint name="base_yaw" axis="0 0 1" pos="0.05 0.02 0"/>
        <geom type="box" size="0.3 0.2 0.1" mass="20"/>{ARM}</body></worldbody>
      <actuator><motor joint="base_x"/><motor joint="base_y"/><motor joint="base_yaw"/>
        <motor joint="shoulder"/><motor joint="elbow"/></actuator></mujoco>""",
    # scene bodies before the robot: a free box (its 7 coordinates come first in qpos), a static
    # wall with mass, a mocap target; the robot's q maps into the plant's qpos by index
    "scene_with_props": f"""<mujoco>{DEFAULTS}<worldbody>
      <geom name="floor" type="plane" size="2 2 0.1"/>
      <body name="box" pos="0.5 0.3 0.05"><freejoint name="box_free"/>
        <geom type="box" size="0.05 0.05 0.05" mass="0.4"/></body>
      <body name="wall" pos="1 0 0.5"><geom type="box" size="0.05 1 0.5" mass="50"/></body>
      <body name="target" mocap="true" pos="0.3 0 0.4"><site name="target_site"/>
        <geom type="sphere" size="0.02" contype="0" conaffinity="0" mass="0.1"/></body>
      <body name="mount" pos="0 0 0.3" euler="20 0 30">
        <geom type="cylinder" size="0.05 0.05" mass="3"/>{ARM}</body></worldbody>
      <actuator><motor joint="shoulder"/><position joint="elbow" kp="50"/></actuator></mujoco>""",
    "one_hinge": f"""<mujoco>{DEFAULTS}<worldbody>
      <body name="link" pos="0 0 0.5" euler="0 0 25"><joint name="shoulder" axis="0.2 1 0.3"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
        <site name="tool" pos="0.3 0 0.02"/></body></worldbody>
      <actuator><motor joint="shoulder"/></actuator></mujoco>""",
    "ball_and_unaligned": f"""<mujoco>{DEFAULTS}<worldbody>
      <body name="upper" pos="0 0 0.4" quat="0.9 0.1 0.3 0.2">
        <joint name="shoulder" type="ball" pos="0.01 0.02 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1.2"/>
        <body name="fore" pos="0.3 0 0">
          <joint name="elbow" axis="0.3 0.8 0.2" pos="0.02 0 0.01" range="-100 100" limited="true"/>
          <joint name="wrist" axis="1 1 0" pos="0.2 0 0" range="-100 100" limited="true"/>
          <geom type="box" size="0.12 0.02 0.02" pos="0.12 0 0.01" mass="0.7"/>
          <site name="tool" class="marker"/></body></body></worldbody>
      <actuator><motor joint="elbow"/><motor joint="wrist"/></actuator></mujoco>""",
    "two_trees": f"""<mujoco>{DEFAULTS}<worldbody>
      <body name="mount_b" pos="0.5 0 0" euler="0 0 180">{ARM.replace('name="', 'name="b_')}</body>
      <body name="mount" pos="-0.5 0 0">{ARM}</body></worldbody>
      <actuator><motor joint="shoulder"/><motor joint="elbow"/><motor joint="b_shoulder"/>
        <motor joint="b_elbow"/></actuator></mujoco>""",
    # no names on bodies, on a joint, on a site: both engines call them body<id>, joint<id>, site<id>
    "unnamed_parts": f"""<mujoco>{DEFAULTS}<worldbody>
      <body pos="0 0 0.5" euler="10 0 25"><joint axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
        <body pos="0.3 0 0"><joint name="elbow" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.03" mass="0.6"/>
          <site pos="0.25 0 0"/><site name="tool" pos="0.25 0 0.02"/></body></body></worldbody>
      <actuator><motor joint="elbow"/></actuator></mujoco>""",
}


@pytest.fixture(params=sorted(ROBOTS))
def robot_file(request, tmp_path):
    path = tmp_path / f"{request.param}.xml"
    path.write_text(ROBOTS[request.param])
    return path


def test_loads_and_cross_checks_at_1e9(robot_file):
    robot = load_robot(robot_file)  # the load-time agreement check (mass, FK of every body and site)
    assert robot.source.analytic == "mujoco"
    report = crosscheck(robot, n_states=30, seed=1)
    assert report.passed and report.complete, report.to_text()
    assert max(q.max_rel_error for q in report.quantities) < 1e-9


def test_unnamed_parts_are_named_alike_in_both_engines(tmp_path):
    path = tmp_path / "unnamed.xml"
    path.write_text(ROBOTS["unnamed_parts"])
    robot = load_robot(path)
    assert list(robot.joints) == ["joint0", "elbow"]
    assert {"body1", "body2"} <= set(robot.bodies) and "site0" in robot.sites
    assert all(robot.pin_model.existFrame(n) for n in ("body1", "body2", "site0", "tool"))


def test_ik_solution_lands_in_mujoco(robot_file, tmp_path):
    # a reachable target: where MuJoCo puts the tool at another configuration of the robot
    robot = load_robot(robot_file)
    q = robot.neutral_q()
    for k, j in enumerate(robot.joints.values()):
        if j.kind in ("hinge", "slide"):
            q[j.idx_q] = (0.4, -0.6, 0.3)[k % 3]
        elif j.kind == "ball":
            q[j.q_slice] = np.array([0.2, -0.1, 0.3, 0.9]) / np.linalg.norm([0.2, -0.1, 0.3, 0.9])
    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    robot.plant_qpos(q, d.qpos)
    mujoco.mj_kinematics(m, d)
    target = ",".join(f"{x:.6f}" for x in d.site_xpos[robot.site_id("tool")])
    out = tmp_path / "ik"
    result = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "ik", str(robot_file), "--target", f"tool={target}",
         "--output", str(out), "--quiet"],
        capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    values = json.loads((out / "report.json").read_text())["values"]
    assert values["max_plant_residual_m"] < 1e-3  # measured with MuJoCo's kinematics


def test_parser_model_that_drops_the_root_pose_never_loads_silently(tmp_path):
    path = tmp_path / "rotated_root.xml"
    path.write_text(ROBOTS["rotated_root"])
    # Pinocchio's MJCF parser drops the jointless root body's pose: the load-time check measures it
    # ... and the site inside a <frame>, which it drops too
    with pytest.raises(ModelMismatchError, match="disagree: missing in Pinocchio: site 'framed'"):
        load_robot(path, analytic="parser")
    frame = '    <frame pos="0.1 0 0.05" euler="0 45 0"><site name="framed" pos="0.05 0 0"/></frame>\n'
    assert frame in ROBOTS["rotated_root"]
    path.write_text(ROBOTS["rotated_root"].replace(frame, ""))
    fk = r"disagree: forward kinematics differ by [\d.]+ \(m or rotation entry\) at "
    with pytest.raises(ModelMismatchError, match=fk):
        load_robot(path, analytic="parser")
    assert load_robot(path).source.analytic == "mujoco"  # the default path loads it
