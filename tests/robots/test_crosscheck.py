"""Pinocchio-vs-MuJoCo dynamics cross-check: known robots pass, modelling errors fail by name."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from mbctl.robots import load_robot
from mbctl.robots.crosscheck import TOLERANCES, CrossCheckError, Tolerance, crosscheck
from mbctl.robots.crosscheck.locate import ROLES
from mbctl.robots.crosscheck.report import ACCOUNTED, EXCLUDED, NOT_COMPARED
from mbctl.robots.crosscheck.sampling import sample_states
from mbctl.robots.registry import ASSETS

ALL_QUANTITIES = ("structure", *TOLERANCES)

# A floating-base robot with two ball joints, an unaligned hinge, a slide, joint position offsets,
# a site with a rotation, damping, and a static body with mass after the robot (Pinocchio's MJCF
# parser reads the first tree only).
BALL_FREE_XML = """
<mujoco model="ball_free_leg">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option gravity="0.3 -0.2 -9.81"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="base" pos="0 0 0.5">
      <freejoint name="root"/>
      <inertial pos="0.01 0.02 -0.01" mass="5" fullinertia="0.1 0.12 0.15 0.01 -0.005 0.002"/>
      <geom type="box" size="0.2 0.1 0.05"/>
      <site name="imu" pos="0.05 0 0.02" quat="0.9 0.1 0.2 0.3"/>
      <body name="thigh" pos="0.2 0.1 0" quat="0.96 0 0.28 0">
        <joint name="hip" type="ball" armature="0.01" damping="0.5"/>
        <inertial pos="0 0.01 -0.1" quat="0.9 0.3 0 0.1" mass="1" diaginertia="0.01 0.012 0.003"/>
        <body name="shin" pos="0 0 -0.2">
          <joint name="knee" type="hinge" axis="0 1 0.2" range="-2 0.5" pos="0 0 0.01"/>
          <inertial pos="0 0 -0.1" mass="0.5" diaginertia="0.004 0.004 0.001"/>
          <body name="foot" pos="0 0 -0.2">
            <joint name="ankle" type="slide" axis="0 0 1" range="-0.05 0.05" armature="0.1"/>
            <inertial pos="0 0 -0.02" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
            <site name="toe" pos="0.03 0 -0.04"/>
          </body>
        </body>
      </body>
      <body name="arm" pos="-0.2 0 0.1">
        <joint name="shoulder" type="ball"/>
        <inertial pos="0 0 0.1" mass="0.8" diaginertia="0.005 0.005 0.001"/>
        <body name="forearm" pos="0 0 0.2">
          <joint name="elbow" axis="1 0 0" armature="0.03"/>
          <inertial pos="0 0 0.1" mass="0.4" diaginertia="0.002 0.002 0.0005"/>
        </body>
      </body>
    </body>
    <body name="pedestal" pos="2 0 0.1">
      <inertial pos="0 0 0" mass="3" diaginertia="0.1 0.1 0.1"/>
      <geom type="box" size="0.1 0.1 0.1"/>
    </body>
  </worldbody>
</mujoco>
"""

# Two hinges coupled by a spring tendon and a binding joint equality; one body with gravcomp.
COUPLED_XML = """
<mujoco model="coupled">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="a">
      <joint name="j1" axis="0 1 0"/>
      <inertial pos="0.15 0 0" mass="1" diaginertia="0.001 0.01 0.01"/>
      <body name="b" pos="0.3 0 0" gravcomp="1">
        <joint name="j2" axis="0 1 0"/>
        <inertial pos="0.15 0 0" mass="0.5" diaginertia="0.001 0.005 0.005"/>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="coupling" stiffness="10">
      <joint joint="j1" coef="1"/>
      <joint joint="j2" coef="-1"/>
    </fixed>
  </tendon>
  <equality>
    <joint name="mimic" joint1="j2" joint2="j1" polycoef="0 1 0 0 0"/>
  </equality>
</mujoco>
"""

# A single hinge (nv = 1: Pinocchio returns its (6, 1) Jacobians as vectors), limited, with
# armature, an offset inertial frame and a site.
ONE_HINGE_XML = """
<mujoco model="one_hinge">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="link" pos="0 0 0.1">
      <joint name="hinge" axis="0 1 0" range="-1.5 1.5" armature="0.01"/>
      <inertial pos="0.1 0 0.01" mass="1" diaginertia="0.001 0.01 0.01"/>
      <site name="tip" pos="0.2 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""

# A three-hinge chain; the Pinocchio side of the structure test drops j2 (b welded to a).
CHAIN_XML = """
<mujoco model="chain">
  <compiler angle="radian" inertiafromgeom="false"/>
  <worldbody>
    <body name="a">
      <joint name="j1" axis="0 0 1"/>
      <inertial pos="0.1 0 0" mass="1" diaginertia="0.001 0.01 0.01"/>
      <body name="b" pos="0.2 0 0">
        <joint name="j2" axis="0 0 1"/>
        <inertial pos="0.1 0 0" mass="1" diaginertia="0.001 0.01 0.01"/>
        <body name="c" pos="0.2 0 0">
          <joint name="j3" axis="0 0 1"/>
          <inertial pos="0.1 0 0" mass="1" diaginertia="0.001 0.01 0.01"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


# The 2-link arm as URDF: same kinematics and inertias, but URDF cannot carry armature.
ARM_URDF = """<?xml version="1.0"?>
<robot name="two_link_arm">
  <link name="world"/>
  <joint name="shoulder" type="revolute">
    <parent link="world"/><child link="link1"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="30" velocity="10"/>
  </joint>
  <link name="link1">
    <inertial><origin xyz="0.15 0 0"/><mass value="1.0"/>
      <inertia ixx="0.000242" iyy="0.007621" izz="0.007621" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="link1"/><child link="link2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="20" velocity="10"/>
  </joint>
  <link name="link2">
    <inertial><origin xyz="0.15 0 0"/><mass value="0.7"/>
      <inertia ixx="0.0001134" iyy="0.0053067" izz="0.0053067" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="ee_fixed" type="fixed">
    <parent link="link2"/><child link="ee_body"/><origin xyz="0.3 0 0"/>
  </joint>
  <link name="ee_body">
    <inertial><origin xyz="0 0 0"/><mass value="0.05"/>
      <inertia ixx="2e-6" iyy="2e-6" izz="2e-6" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="ee_site_joint" type="fixed">
    <parent link="ee_body"/><child link="end_effector"/><origin xyz="0.015 0 0"/>
  </joint>
  <link name="end_effector"/>
</robot>
"""


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _assert_clean_pass(report, bound: float = 1e-12) -> None:
    assert report.passed and report.complete, report.to_text()
    assert report.failed == ()
    for q in report.quantities:
        assert q.status == "pass", q
        assert q.max_rel_error <= bound, q  # measured <= 2e-14; the tolerance is 1e-9


# ---------------------------------------------------------------- known robots pass


@pytest.mark.parametrize("name", ["two_link", "two_link_torque", "two_link_torque_gravity"])
def test_two_link_arms_agree_to_round_off(name, request):
    report = crosscheck(request.getfixturevalue(name), n_states=200, seed=0)
    _assert_clean_pass(report)
    assert report.n_states == 202  # 200 random + neutral at rest + random at rest
    assert tuple(q.name for q in report.quantities) == ALL_QUANTITIES
    assert [f.feature for f in report.features] == ["actuators"]


def test_two_link_with_gravity_compares_nonzero_gravity(two_link_torque_gravity):
    report = crosscheck(two_link_torque_gravity, n_states=50, seed=1)
    # The gravity torques are compared against their own magnitude, not against the floor.
    assert report.quantity("gravity").max_abs_error > 0.0
    assert report.quantity("potential_energy").max_rel_error < 1e-12


def test_g1_agrees_to_round_off(g1):
    report = crosscheck(g1, n_states=150, seed=0)
    _assert_clean_pass(report)
    assert report.state_kinds == {
        "neutral, v = 0": 1,
        "zero velocity": 1,
        "lower limits": 1,
        "upper limits": 1,
        "random": 150,
    }
    handled = {f.feature: f.handling for f in report.features}
    assert handled == {
        "contact": EXCLUDED,
        "joint limits": EXCLUDED,
        "frictionloss": EXCLUDED,
        "actuators": EXCLUDED,
    }
    assert report.notes == ()
    # The caller's plant is untouched: the private copy carries the disable flags.
    assert g1.mj_model.opt.disableflags == 0
    assert not g1.mj_model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_ENERGY


def test_g1_edge_states_sit_on_the_limits(g1):
    states = sample_states(g1, n_states=5, seed=2)
    m = g1.mj_model
    hinge_q = [j.idx_q for j in g1.joints.values() if j.kind == "hinge"]
    jids = [i for i, j in enumerate(g1.joints.values()) if j.kind == "hinge"]
    np.testing.assert_array_equal(states.q[2, hinge_q], m.jnt_range[jids, 0])
    np.testing.assert_array_equal(states.q[3, hinge_q], m.jnt_range[jids, 1])
    assert np.all(states.v[:2] == 0.0)
    quat = states.q[:, 3:7]
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-15)
    rand = states.q[4:, hinge_q]
    assert np.all((rand >= m.jnt_range[jids, 0]) & (rand <= m.jnt_range[jids, 1]))


# ---------------------------------------------------------------- robots users bring


def test_free_and_ball_joints_agree(tmp_path):
    robot = load_robot(_write(tmp_path, "leg.xml", BALL_FREE_XML), check=False)
    assert [j.kind for j in robot.joints.values()] == ["free", "ball", "hinge", "slide", "ball", "hinge"]
    report = crosscheck(robot, n_states=200, seed=3)
    assert report.passed and report.failed == ()
    for q in report.quantities:
        assert q.max_rel_error <= 1e-12, q
    handled = {f.feature: f.handling for f in report.features}
    assert handled["static bodies with mass"] == ACCOUNTED  # the pedestal's potential energy
    assert handled["damping"] == EXCLUDED
    # Built from the compiled plant, the pedestal's mass is in both models: nothing to explain.
    assert not any("robot mass differs" in n for n in report.notes)
    # The pedestal is a tree without joints: scene, not robot, in both analytic paths.
    assert "pedestal" not in robot.bodies and "pedestal" in robot.scene_bodies[0]
    scene = next(f for f in report.features if f.feature == "scene bodies")
    assert scene.handling == EXCLUDED and "pedestal (static, 3 kg)" in scene.detail
    parsed = crosscheck(load_robot(robot.source.robot_file, check=False, analytic="parser"), n_states=20)
    assert parsed.passed and parsed.notes == ()


def test_one_hinge_robot_agrees(tmp_path):
    robot = load_robot(_write(tmp_path, "one_hinge.xml", ONE_HINGE_XML), check=False)
    assert robot.nv == 1
    for chunk_size in (1, 16):
        report = crosscheck(robot, n_states=40, seed=0, chunk_size=chunk_size)
        _assert_clean_pass(report)
        assert report.n_states == 44  # 40 random + rest + rest + lower and upper limits
    assert report.quantity("gravity").max_abs_error > 0.0  # compared, not vanishing


def test_one_hinge_failure_names_the_joint(tmp_path):
    robot_file = _write(tmp_path, "one_hinge.xml", ONE_HINGE_XML)
    heavier = _write(tmp_path, "heavier.xml", ONE_HINGE_XML.replace('mass="1"', 'mass="1.01"'))
    robot = load_robot(robot_file, pin_model_file=heavier, check=False)
    report = crosscheck(robot, n_states=10, seed=0)
    assert "gravity" in report.failed
    assert report.quantity("gravity").worst_entry == "v[0] (hinge)"
    assert report.quantity("mass_matrix").worst_entry == "row v[0] (hinge), column v[0] (hinge)"


def test_tendon_equality_gravcomp_are_not_compared(tmp_path):
    robot = load_robot(_write(tmp_path, "coupled.xml", COUPLED_XML), check=False)
    report = crosscheck(robot, n_states=50, seed=0)
    handled = {f.feature: f.handling for f in report.features}
    assert handled == {
        "equality constraints": NOT_COMPARED,
        "gravity compensation": NOT_COMPARED,
        "tendons": NOT_COMPARED,
    }
    assert report.passed  # the rigid-body part agrees ...
    assert not report.complete  # ... but no clean pass is claimed
    assert report.not_compared == ("equality constraints", "gravity compensation", "tendons")
    assert report.verdict.startswith("PASS (incomplete: not compared: equality constraints")
    assert "NOT COMPARED" in report.to_text()
    assert report.to_dict()["complete"] is False


# Armature on every kind of joint, on axes off the coordinate axes too: Pinocchio 4.1's
# computeKineticEnergy leaves out the armature of a revolute joint with an unaligned axis.
ARMATURE_XML = """
<mujoco model="armature">
  <compiler angle="radian" inertiafromgeom="false"/>
  <worldbody>
    <body name="base" pos="0 0 0.5"><freejoint name="root"/>
      <inertial pos="0 0 0" mass="3" diaginertia="0.05 0.06 0.07"/>
      <body name="l1"><joint name="tilted_hinge" axis="0 0.6 0.8" armature="0.05"/>
        <inertial pos="0.1 0 0" mass="1" diaginertia="0.001 0.01 0.01"/>
        <body name="l2" pos="0.2 0 0"><joint name="tilted_slide" type="slide" axis="1 1 0" armature="0.2"/>
          <inertial pos="0.05 0 0" mass="0.5" diaginertia="0.001 0.002 0.002"/>
          <body name="l3" pos="0.1 0 0"><joint name="hinge_y" axis="0 1 0" armature="0.03"/>
            <inertial pos="0.05 0 0" mass="0.3" diaginertia="0.001 0.001 0.001"/>
            <body name="l4" pos="0.1 0 0"><joint name="ball" type="ball" armature="0.01"/>
              <inertial pos="0.05 0 0" mass="0.2" diaginertia="0.001 0.001 0.001"/></body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_kinetic_energy_counts_armature_on_both_sides(tmp_path):
    robot = load_robot(_write(tmp_path, "armature.xml", ARMATURE_XML))
    assert robot.pin_model.joints[2].shortname() == "JointModelRevoluteUnaligned"
    report = crosscheck(robot, n_states=50, seed=3)
    _assert_clean_pass(report)
    assert report.quantity("kinetic_energy").max_abs_error > 0.0  # compared, not vanishing
    # The report says how each side computes the energy, under the quantity's row.
    how = report.quantity("kinetic_energy").note
    assert how == ("Pinocchio: computeKineticEnergy of the rigid bodies + 1/2 v^T diag(armature) v; "
                   "MuJoCo: energy[1] = 1/2 v^T M v, armature in M")
    lines = report.to_text().splitlines()
    row = next(i for i, line in enumerate(lines) if line.startswith("kinetic_energy "))
    assert lines[row + 1] == f"    ({how})"
    assert report.to_dict()["quantities"][list(ALL_QUANTITIES).index("kinetic_energy")]["note"] == how


def test_kinetic_energy_without_armature_in_pinocchio_fails(tmp_path):
    robot_file = _write(tmp_path, "armature.xml", ARMATURE_XML)
    bare = _write(tmp_path, "bare.xml", ARMATURE_XML.replace(' armature="0.05"', ""))
    report = crosscheck(load_robot(robot_file, pin_model_file=bare, check=False), n_states=20, seed=0)
    assert "kinetic_energy" in report.failed and "mass_matrix" in report.failed


def test_unaligned_hinge_armature_passes_on_the_leg(tmp_path):
    xml = BALL_FREE_XML.replace('axis="0 1 0.2" range', 'axis="0 1 0.2" armature="0.02" range')
    report = crosscheck(load_robot(_write(tmp_path, "leg_arm.xml", xml), check=False), n_states=50, seed=3)
    assert report.passed and report.failed == (), report.to_text()


def test_robot_after_another_top_level_body_fails_structure(tmp_path):
    first, rest = BALL_FREE_XML.split('    <body name="pedestal"')
    pedestal, tail = rest.split("    </body>\n  </worldbody>")
    xml = (
        first.replace(
            '    <body name="base"',
            '    <body name="pedestal"' + pedestal + '    </body>\n    <body name="base"',
        )
        + "  </worldbody>"
        + tail
    )
    path = _write(tmp_path, "pedestal_first.xml", xml)
    # the default analytic model is built from the compiled plant: every tree, in order
    assert crosscheck(load_robot(path, check=False), n_states=10, seed=0).passed
    # Pinocchio's parser builds only the first tree: the report says so
    robot = load_robot(path, check=False, analytic="parser")
    report = crosscheck(robot, n_states=10, seed=0)
    assert not report.passed
    assert report.failed == ("structure",)
    why = report.quantity("structure").note
    assert why.startswith("sizes differ: Pinocchio nq=0, nv=0; MuJoCo robot nq=18")
    assert "builds only the first body tree" in report.quantity("structure").note
    assert "only in MuJoCo: root, hip, knee, ankle, shoulder, elbow;" in report.quantity("structure").note
    assert "    -> structure failed: sizes differ" in report.to_text()
    assert set(report.not_compared) == set(TOLERANCES)
    json.dumps(report.to_dict(), allow_nan=False)  # NaN errors become null


def test_structure_mismatch_names_the_joints_that_differ(tmp_path):
    chain = _write(tmp_path, "chain.xml", CHAIN_XML)
    lhs, rhs = CHAIN_XML.split('        <joint name="j2" axis="0 0 1"/>\n')
    two = _write(tmp_path, "two.xml", lhs + rhs)
    robot = load_robot(chain, pin_model_file=two, check=False)
    report = crosscheck(robot, n_states=5, seed=0)
    assert report.failed == ("structure",)
    why = report.quantity("structure").note
    assert "sizes differ: Pinocchio nq=2, nv=2; MuJoCo robot nq=3, nv=3" in why
    assert "joints do not pair by name (Pinocchio 2, MuJoCo 3 joints); only in MuJoCo: j2" in why
    assert "only in Pinocchio" not in why
    assert f"    -> structure failed: {why}" in report.to_text().splitlines()


def test_plant_without_gravity_fails_gravity_terms_springs_and_fluid_excluded(tmp_path):
    xml = COUPLED_XML.replace('gravcomp="1"', "").replace(
        '<option gravity="0 0 -9.81"/>',
        '<option gravity="0 0 -9.81" density="1.2" viscosity="1e-5"><flag gravity="disable"/></option>',
    )
    xml = xml.split("  <tendon>")[0] + "</mujoco>\n"
    xml = xml.replace('<joint name="j1" axis="0 1 0"/>', '<joint name="j1" axis="0 1 0" stiffness="5"/>')
    robot = load_robot(_write(tmp_path, "no_gravity.xml", xml), check=False)
    report = crosscheck(robot, n_states=20, seed=0)
    handled = {f.feature: f.handling for f in report.features}
    assert handled == {
        "springs": EXCLUDED,
        "fluid forces": EXCLUDED,
        "gravity disabled in the plant": EXCLUDED,
    }
    # Pinocchio keeps opt.gravity, the plant has none: the difference shows, it is not hidden.
    assert report.failed == ("gravity", "bias", "forward_dynamics", "inverse_dynamics", "potential_energy")


def test_g1_states_exercise_the_free_flyer_bias_term(g1):
    states = sample_states(g1, n_states=20, seed=0)
    extra = [
        np.abs(g1.converter.velocity_map_dot_v(q, v)).max() for q, v in zip(states.q, states.v, strict=True)
    ]
    assert max(extra) > 0.1  # the M Tdot v term in b_pin is far above the 1e-9 tolerance


# ---------------------------------------------------------------- the check catches real errors


def _mutated_arm(tmp_path: Path, old: str, new: str):
    text = (ASSETS / "two_link_arm.xml").read_text()
    assert text.count(old) == 1
    path = _write(tmp_path, "arm.xml", text.replace(old, new))
    robot = load_robot("two_link_torque", gravity=True, pin_model_file=path, check=False)
    return crosscheck(robot, n_states=30, seed=0)


DYNAMICS = ("mass_matrix", "gravity", "bias", "forward_dynamics", "inverse_dynamics")


def test_one_percent_mass_change_fails_mass_matrix_and_gravity(tmp_path):
    report = _mutated_arm(tmp_path, 'pos="0.15 0 0" mass="0.7"', 'pos="0.15 0 0" mass="0.707"')
    assert set(DYNAMICS) <= set(report.failed)
    assert {"fk_position", "fk_rotation", "jacobian_linear", "jacobian_angular"}.isdisjoint(report.failed)
    assert report.quantity("gravity").max_rel_error > 1e-3
    assert any("robot mass differs: Pinocchio 1.757 kg, MuJoCo 1.75 kg" in n for n in report.notes)


def test_flipped_axis_fails_kinematics(tmp_path):
    report = _mutated_arm(tmp_path, '<joint name="elbow"/>', '<joint name="elbow" axis="0 0 -1"/>')
    for name in ("fk_position", "fk_rotation", "jacobian_linear", "jacobian_angular"):
        assert report.quantity(name).status == "fail"
        assert report.quantity(name).max_rel_error > 1e-2
    # The load-time check compares FK of every body and site, so it sees the flipped axis too.
    assert any("agreement check" in n and "forward kinematics differ" in n for n in report.notes)


def test_missing_armature_fails_mass_matrix_only_where_armature_enters(tmp_path):
    report = _mutated_arm(tmp_path, ' armature="0.002"', "")
    assert report.failed == ("mass_matrix", "forward_dynamics", "inverse_dynamics", "kinetic_energy")
    mass_matrix = report.quantity("mass_matrix")
    assert mass_matrix.max_abs_error == pytest.approx(0.002, rel=1e-9)
    # The armature sits on the diagonal: the worst entry is M[i, i] of one of the two joints.
    assert mass_matrix.worst_entry in (
        "row v[0] (shoulder), column v[0] (shoulder)",
        "row v[1] (elbow), column v[1] (elbow)",
    )


def test_failing_rows_say_why_in_the_text_report(tmp_path):
    report = _mutated_arm(tmp_path, '<joint name="elbow"/>', '<joint name="elbow" axis="0 0 -1"/>')
    lines = report.to_text().splitlines()
    for name in report.failed:
        q = report.quantity(name)
        row = next(i for i, line in enumerate(lines) if line.startswith(f"{name} "))
        why = lines[row + 1]
        assert why == f"    -> {q.reason}"
        assert why.startswith(
            f"    -> {name} failed: max rel error {q.max_rel_error:.3e} > tolerance 1.0e-09"
        )
        assert (
            f"max abs error {q.max_abs_error:.3e} {q.unit} at state {q.worst_state} ({q.worst_state_kind})"
            in why
        )
    # Frame quantities name the frame, the axis and (for Jacobians) the joint of the column.
    jac = report.quantity("jacobian_angular")
    assert jac.worst_entry.startswith(
        ("body 'link2', axis", "body 'ee_body', axis", "site 'end_effector', axis")
    )
    assert jac.worst_entry.endswith("column v[1] (elbow)")
    assert report.quantity("fk_position").worst_entry.endswith(("axis x", "axis y", "axis z"))
    # Passing rows carry no reason; JSON has both fields.
    assert report.quantity("structure").reason == "" and report.quantity("structure").worst_entry == ""
    data = report.to_dict()["quantities"]
    assert data[1]["name"] == "fk_position" and data[1]["reason"] == report.quantity("fk_position").reason


def test_every_quantity_has_named_axes():
    assert list(ROLES) == list(TOLERANCES)


def test_shifted_inertial_frame_fails_com_and_mass_matrix(tmp_path):
    report = _mutated_arm(tmp_path, 'pos="0.15 0 0" mass="0.7"', 'pos="0.16 0 0" mass="0.7"')
    assert {"com", "com_jacobian", "mass_matrix"} <= set(report.failed)
    assert {"fk_position", "jacobian_linear"}.isdisjoint(report.failed)
    # Same total mass: invisible to the load-time check, but located among the model differences.
    assert len(report.notes) == 1 and report.notes[0].startswith(
        "the models differ (Pinocchio vs MuJoCo, at q0, world frame): link2, ee_body (joint 'elbow'): "
        "centre of mass at q0 (0.469333, 0, 0) vs (0.46, 0, 0) m; "  # link2 and the welded ee_body
    )


def test_urdf_pin_model_differs_only_by_armature(tmp_path):
    path = _write(tmp_path, "arm.urdf", ARM_URDF)
    robot = load_robot("two_link_torque", gravity=True, pin_model_file=path, check=False)
    report = crosscheck(robot, n_states=30, seed=0)
    assert report.failed == ("mass_matrix", "forward_dynamics", "inverse_dynamics", "kinetic_energy")
    for name in ("fk_position", "jacobian_linear", "com", "gravity", "bias", "momentum_angular"):
        assert report.quantity(name).max_rel_error < 1e-12
    assert report.pin_model_file == str(path)
    assert any("armature differs at dofs [0, 1]" in n for n in report.notes)
    assert not any("no Pinocchio frame" in n for n in report.notes)  # the site is a URDF link


# ---------------------------------------------------------------- report and errors


def test_report_json_and_text(two_link_torque):
    report = crosscheck(two_link_torque, n_states=5, seed=7)
    data = json.loads(json.dumps(report.to_dict(), allow_nan=False))
    assert data["passed"] is True and data["verdict"] == "PASS"
    assert [q["name"] for q in data["quantities"]] == list(ALL_QUANTITIES)
    assert data["quantities"][1]["tolerance"] == 1e-9
    text = report.to_text()
    assert text.splitlines()[-1] == "result: PASS"
    assert "mass_matrix" in text and "kg m^2" in text


def test_same_seed_same_states(two_link_torque):
    a = sample_states(two_link_torque, 10, seed=4)
    b = sample_states(two_link_torque, 10, seed=4)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.tau, b.tau)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_states": -1}, "n_states must be an integer >= 0; got -1"),
        ({"n_states": 2.5}, "n_states must be an integer >= 0; got 2.5"),
        ({"seed": "x"}, "seed must be an integer >= 0; got 'x'"),
        ({"chunk_size": 0}, "chunk_size must be an integer >= 1; got 0"),
        ({"tolerances": {}}, "tolerances has no entry for fk_position"),
        (
            {"progress": 3},
            r"progress must be a callable progress\(done_states, total_states\) or None; got 3",
        ),
    ],
)
def test_bad_arguments_raise(two_link, kwargs, match):
    with pytest.raises(CrossCheckError, match=match):
        crosscheck(two_link, **kwargs)


def test_bad_tolerance_raises():
    with pytest.raises(CrossCheckError, match="Tolerance.rtol must be a positive finite number; got 0.0"):
        Tolerance(0.0, 1.0, "m", "x")


def test_progress_counts_states_up_to_the_total(two_link_torque):
    calls: list[tuple[int, int]] = []
    report = crosscheck(
        two_link_torque,
        n_states=37,
        seed=0,
        chunk_size=8,
        progress=lambda done, total: calls.append((done, total)),
    )
    done = [d for d, _ in calls]
    assert done == [8, 16, 24, 32, 39]  # one call per chunk of 8, the last one partial
    assert all(a < b for a, b in zip(done, done[1:], strict=False))
    assert {total for _, total in calls} == {report.n_states} == {39}


def test_progress_is_not_called_without_states_to_evaluate(tmp_path):
    chain = _write(tmp_path, "chain.xml", CHAIN_XML)
    lhs, rhs = CHAIN_XML.split('        <joint name="j2" axis="0 0 1"/>\n')
    robot = load_robot(chain, pin_model_file=_write(tmp_path, "two.xml", lhs + rhs), check=False)
    calls: list[tuple[int, int]] = []
    crosscheck(robot, n_states=5, progress=lambda done, total: calls.append((done, total)))
    assert calls == []


def test_chunking_does_not_change_results(g1):
    a = crosscheck(g1, n_states=20, seed=5, chunk_size=3)
    b = crosscheck(g1, n_states=20, seed=5, chunk_size=64)
    assert [q.max_abs_error for q in a.quantities] == [q.max_abs_error for q in b.quantities]


# ---------------------------------------------------------------- CLI


def _mbctl(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "mbctl.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ),
    )


def test_cli_xcheck_passes_and_writes_json(tmp_path):
    out = _mbctl(
        "xcheck", "two_link_torque", "--states", "20", "--seed", "3", "--json", str(tmp_path / "r.json")
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == "result: PASS"
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["n_states"] == 22 and data["seed"] == 3 and data["passed"] is True


def test_cli_xcheck_exits_1_on_a_different_pin_model(tmp_path):
    text = (ASSETS / "two_link_arm.xml").read_text().replace(' armature="0.002"', "")
    arm = _write(tmp_path, "arm.xml", text)
    out = _mbctl("xcheck", "two_link_torque", "--states", "10", "--pin-model", str(arm))
    assert out.returncode == 1, out.stderr
    assert "load-time agreement check found differences" in out.stdout
    assert out.stdout.splitlines()[-1] == "result: FAIL"


# ---------------------------------------------------------------- the batched evaluation


def _evaluator(robot, n_states=20, seed=0, chunk=8):
    from mbctl.robots.crosscheck.evaluator import Evaluator, match_frames
    from mbctl.robots.crosscheck.plant import comparison_model

    m, _ = comparison_model(robot.mj_model, robot.scene_body_ids)
    states = sample_states(robot, n_states, seed)
    evaluator = Evaluator(robot, m, match_frames(robot), chunk)
    evaluator._evaluate(states, 0, chunk)
    return evaluator, states


@pytest.mark.parametrize("name", ["g1", "leg"])
def test_batched_frame_jacobians_equal_get_frame_jacobian(name, request, tmp_path):
    import pinocchio as pin

    robot = (request.getfixturevalue("g1") if name == "g1"
             else load_robot(_write(tmp_path, "leg.xml", BALL_FREE_XML), check=False))
    evaluator, states = _evaluator(robot)
    P, _ = evaluator.aligned(evaluator.chunk, full=True)
    pm, pd = robot.pin_model, robot.pin_model.createData()
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for i in (0, 3, 7):  # slots of the chunk: states 0, 3, 7
        pin.computeAllTerms(pm, pd, states.q[i], states.v[i])
        pin.updateFramePlacements(pm, pd)
        for k, f in enumerate(evaluator.frames.pin_ids):
            np.testing.assert_allclose(P["jacobian"][i, k], pin.getFrameJacobian(pm, pd, f, lwa), atol=1e-14)
            np.testing.assert_allclose(P["frames"][i, k, :, 3], pd.oMf[f].translation, atol=1e-14)
            np.testing.assert_allclose(P["frames"][i, k, :, :3], pd.oMf[f].rotation, atol=1e-14)


def test_jacobians_compared_on_the_supports_give_the_full_maxima(g1):
    """Outside both engines' supports every entry is exactly zero: the packed maxima are the full ones."""
    for s in (0, 5, 9):  # one state at a time: MuJoCo's dense Jacobians are kept for one state
        evaluator, states = _evaluator(g1, chunk=1)
        evaluator._evaluate(states, s, s + 1)
        packed = evaluator._reduced(*evaluator.aligned(1), 1)
        evaluator._evaluate(states, s, s + 1)
        Pf, Qf = evaluator.aligned(1, full=True)
        outside = np.broadcast_to((evaluator._mask == 0)[None, :, None, :], Pf["jacobian"].shape)
        assert np.all(Pf["jacobian"][outside] == 0.0) and np.all(Qf["jacobian"][outside] == 0.0)
        full = np.abs(Pf["jacobian"] - Qf["jacobian"])
        assert packed["jacobian_linear"][0][0] == full[:, :, :3].max()
        assert packed["jacobian_angular"][0][0] == full[:, :, 3:].max()
        assert packed["jacobian_linear"][1] == np.abs(Qf["jacobian"][:, :, :3]).max()
