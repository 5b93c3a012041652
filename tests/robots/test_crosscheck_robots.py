"""Pinocchio-vs-MuJoCo dynamics cross-check: our robots and the robots users bring agree to round-off.

Test models are in tests/robots/assets/.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from mbctl.robots import load_robot
from mbctl.robots.crosscheck import TOLERANCES, crosscheck
from mbctl.robots.crosscheck.report import ACCOUNTED, EXCLUDED, NOT_COMPARED
from mbctl.robots.crosscheck.sampling import sample_states

ALL_QUANTITIES = ("structure", *TOLERANCES)


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


def test_free_and_ball_joints_agree(asset):
    robot = load_robot(asset("ball_free_leg.xml"), check=False)
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


def test_one_hinge_robot_agrees(asset):
    robot = load_robot(asset("one_hinge.xml"), check=False)
    assert robot.nv == 1
    for chunk_size in (1, 16):
        report = crosscheck(robot, n_states=40, seed=0, chunk_size=chunk_size)
        _assert_clean_pass(report)
        assert report.n_states == 44  # 40 random + rest + rest + lower and upper limits
    assert report.quantity("gravity").max_abs_error > 0.0  # compared, not vanishing


def test_one_hinge_failure_names_the_joint(write_model, asset):
    robot_file = asset("one_hinge.xml")
    heavier_xml = asset("one_hinge.xml").read_text().replace('mass="1"', 'mass="1.01"')
    heavier = write_model("heavier.xml", heavier_xml)
    robot = load_robot(robot_file, pin_model_file=heavier, check=False)
    report = crosscheck(robot, n_states=10, seed=0)
    assert "gravity" in report.failed
    assert report.quantity("gravity").worst_entry == "v[0] (hinge)"
    assert report.quantity("mass_matrix").worst_entry == "row v[0] (hinge), column v[0] (hinge)"


def test_tendon_equality_gravcomp_are_not_compared(asset):
    robot = load_robot(asset("coupled.xml"), check=False)
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


def test_kinetic_energy_counts_armature_on_both_sides(asset):
    robot = load_robot(asset("armature.xml"))
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


def test_kinetic_energy_without_armature_in_pinocchio_fails(write_model, asset):
    robot_file = asset("armature.xml")
    bare = write_model("bare.xml", asset("armature.xml").read_text().replace(' armature="0.05"', ""))
    report = crosscheck(load_robot(robot_file, pin_model_file=bare, check=False), n_states=20, seed=0)
    assert "kinetic_energy" in report.failed and "mass_matrix" in report.failed


def test_unaligned_hinge_armature_passes_on_the_leg(write_model, asset):
    xml = asset("ball_free_leg.xml").read_text()
    xml = xml.replace('axis="0 1 0.2" range', 'axis="0 1 0.2" armature="0.02" range')
    report = crosscheck(load_robot(write_model("leg_arm.xml", xml), check=False), n_states=50, seed=3)
    assert report.passed and report.failed == (), report.to_text()


def test_robot_after_another_top_level_body_fails_structure(write_model, asset):
    first, rest = asset("ball_free_leg.xml").read_text().split('    <body name="pedestal"')
    pedestal, tail = rest.split("    </body>\n  </worldbody>")
    xml = (
        first.replace(
            '    <body name="base"',
            '    <body name="pedestal"' + pedestal + '    </body>\n    <body name="base"',
        )
        + "  </worldbody>"
        + tail
    )
    path = write_model("pedestal_first.xml", xml)
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


def test_structure_mismatch_names_the_joints_that_differ(write_model, asset):
    chain = asset("chain.xml")
    lhs, rhs = asset("chain.xml").read_text().split('        <joint name="j2" axis="0 0 1"/>\n')
    two = write_model("two.xml", lhs + rhs)
    robot = load_robot(chain, pin_model_file=two, check=False)
    report = crosscheck(robot, n_states=5, seed=0)
    assert report.failed == ("structure",)
    why = report.quantity("structure").note
    assert "sizes differ: Pinocchio nq=2, nv=2; MuJoCo robot nq=3, nv=3" in why
    assert "joints do not pair by name (Pinocchio 2, MuJoCo 3 joints); only in MuJoCo: j2" in why
    assert "only in Pinocchio" not in why
    assert f"    -> structure failed: {why}" in report.to_text().splitlines()


def test_plant_without_gravity_fails_gravity_terms_springs_and_fluid_excluded(write_model, asset):
    xml = asset("coupled.xml").read_text().replace('gravcomp="1"', "").replace(
        '<option gravity="0 0 -9.81"/>',
        '<option gravity="0 0 -9.81" density="1.2" viscosity="1e-5"><flag gravity="disable"/></option>',
    )
    xml = xml.split("  <tendon>")[0] + "</mujoco>\n"
    xml = xml.replace('<joint name="j1" axis="0 1 0"/>', '<joint name="j1" axis="0 1 0" stiffness="5"/>')
    robot = load_robot(write_model("no_gravity.xml", xml), check=False)
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

