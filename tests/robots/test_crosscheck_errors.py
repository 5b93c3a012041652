"""The cross-check catches real modelling errors and says where: mass, axis, armature, inertia, URDF."""

from __future__ import annotations

import pytest

from mbctl.robots import load_robot
from mbctl.robots.crosscheck import TOLERANCES, crosscheck
from mbctl.robots.crosscheck.locate import ROLES
from mbctl.robots.registry import ASSETS


def _mutated_arm(write_model, old: str, new: str):
    text = (ASSETS / "two_link_arm.xml").read_text()
    assert text.count(old) == 1
    path = write_model("arm.xml", text.replace(old, new))
    robot = load_robot("two_link_torque", gravity=True, pin_model_file=path, check=False)
    return crosscheck(robot, n_states=30, seed=0)


DYNAMICS = ("mass_matrix", "gravity", "bias", "forward_dynamics", "inverse_dynamics")


def test_one_percent_mass_change_fails_mass_matrix_and_gravity(write_model):
    report = _mutated_arm(write_model, 'pos="0.15 0 0" mass="0.7"', 'pos="0.15 0 0" mass="0.707"')
    assert set(DYNAMICS) <= set(report.failed)
    assert {"fk_position", "fk_rotation", "jacobian_linear", "jacobian_angular"}.isdisjoint(report.failed)
    assert report.quantity("gravity").max_rel_error > 1e-3
    assert any("robot mass differs: Pinocchio 1.757 kg, MuJoCo 1.75 kg" in n for n in report.notes)


def test_flipped_axis_fails_kinematics(write_model):
    report = _mutated_arm(write_model, '<joint name="elbow"/>', '<joint name="elbow" axis="0 0 -1"/>')
    for name in ("fk_position", "fk_rotation", "jacobian_linear", "jacobian_angular"):
        assert report.quantity(name).status == "fail"
        assert report.quantity(name).max_rel_error > 1e-2
    # The load-time check compares FK of every body and site, so it sees the flipped axis too.
    assert any("agreement check" in n and "forward kinematics differ" in n for n in report.notes)


def test_missing_armature_fails_mass_matrix_only_where_armature_enters(write_model):
    report = _mutated_arm(write_model, ' armature="0.002"', "")
    assert report.failed == ("mass_matrix", "forward_dynamics", "inverse_dynamics", "kinetic_energy")
    mass_matrix = report.quantity("mass_matrix")
    assert mass_matrix.max_abs_error == pytest.approx(0.002, rel=1e-9)
    # The armature sits on the diagonal: the worst entry is M[i, i] of one of the two joints.
    assert mass_matrix.worst_entry in (
        "row v[0] (shoulder), column v[0] (shoulder)",
        "row v[1] (elbow), column v[1] (elbow)",
    )


def test_failing_rows_say_why_in_the_text_report(write_model):
    report = _mutated_arm(write_model, '<joint name="elbow"/>', '<joint name="elbow" axis="0 0 -1"/>')
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


def test_shifted_inertial_frame_fails_com_and_mass_matrix(write_model):
    report = _mutated_arm(write_model, 'pos="0.15 0 0" mass="0.7"', 'pos="0.16 0 0" mass="0.7"')
    assert {"com", "com_jacobian", "mass_matrix"} <= set(report.failed)
    assert {"fk_position", "jacobian_linear"}.isdisjoint(report.failed)
    # Same total mass: invisible to the load-time check, but located among the model differences.
    assert len(report.notes) == 1 and report.notes[0].startswith(
        "the models differ (Pinocchio vs MuJoCo, at q0, world frame): link2, ee_body (joint 'elbow'): "
        "centre of mass at q0 (0.469333, 0, 0) vs (0.46, 0, 0) m; "  # link2 and the welded ee_body
    )


def test_urdf_pin_model_differs_only_by_armature(write_model, asset):
    path = write_model("arm.urdf", asset("two_link_arm.urdf").read_text())
    robot = load_robot("two_link_torque", gravity=True, pin_model_file=path, check=False)
    report = crosscheck(robot, n_states=30, seed=0)
    assert report.failed == ("mass_matrix", "forward_dynamics", "inverse_dynamics", "kinetic_energy")
    for name in ("fk_position", "jacobian_linear", "com", "gravity", "bias", "momentum_angular"):
        assert report.quantity(name).max_rel_error < 1e-12
    assert report.pin_model_file == str(path)
    assert any("armature differs at dofs [0, 1]" in n for n in report.notes)
    assert not any("no Pinocchio frame" in n for n in report.notes)  # the site is a URDF link

