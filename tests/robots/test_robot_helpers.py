"""Robot's dynamics and kinematics helpers, against MuJoCo (the plant) and finite differences.

MuJoCo's quantities are converted to Pinocchio's convention with the robot's StateConverter
(``M_pin = T^T M_mj T``, ``b_pin = T^T (b_mj + M_mj Tdot v)``, ``J_pin = J_mj T``), so on the G1
the free-flyer rows and columns are checked too.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import Robot, StateError, UnknownNameError

#: Step [rad] or [m] of the central finite differences, and their tolerance (O(h^2) error).
FD_STEP = 1e-6
FD_ATOL = 1e-7


def random_state(robot: Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random configuration (unit base quaternion) and velocity, Pinocchio convention."""
    if robot.has_floating_base:
        q = pin.randomConfiguration(robot.pin_model, -np.ones(robot.nq), np.ones(robot.nq))
        quat = rng.normal(size=4)
        q[3:7] = quat / np.linalg.norm(quat)
    else:
        q = rng.uniform(-np.pi, np.pi, robot.nq)
    return q, rng.normal(size=robot.nv)


def mujoco_at(robot: Robot, q: np.ndarray, v: np.ndarray) -> mujoco.MjData:
    """MuJoCo data after mj_forward at (q, v) given in Pinocchio's convention."""
    d = mujoco.MjData(robot.mj_model)
    d.qpos[:] = robot.converter.q_pin_to_mj(q)
    d.qvel[:] = robot.converter.v_pin_to_mj(q, v)
    mujoco.mj_forward(robot.mj_model, d)
    return d


def mujoco_mass_matrix(robot: Robot, d: mujoco.MjData) -> np.ndarray:
    M = np.zeros((robot.nv, robot.nv))
    mujoco.mj_fullM(robot.mj_model, d, M)
    return M


def mujoco_site_jacobian(robot: Robot, q: np.ndarray, d: mujoco.MjData, site: str) -> np.ndarray:
    """MuJoCo's site Jacobian (6, nv), world-aligned, columns in Pinocchio's v convention."""
    jacp, jacr = np.zeros((3, robot.nv)), np.zeros((3, robot.nv))
    mujoco.mj_jacSite(robot.mj_model, d, jacp, jacr, robot.site_id(site))
    return np.vstack([jacp, jacr]) @ robot.converter.velocity_map(q)


def fd_jacobian(robot: Robot, frame: str, q: np.ndarray) -> np.ndarray:
    """World-aligned Jacobian by central differences of frame_pose along each tangent direction."""
    J = np.zeros((6, robot.nv))
    for k in range(robot.nv):
        dv = np.zeros(robot.nv)
        dv[k] = FD_STEP
        p_plus, R_plus = robot.frame_pose(frame, pin.integrate(robot.pin_model, q, dv))
        p_minus, R_minus = robot.frame_pose(frame, pin.integrate(robot.pin_model, q, -dv))
        J[:3, k] = (p_plus - p_minus) / (2 * FD_STEP)
        J[3:, k] = pin.log3(R_plus @ R_minus.T) / (2 * FD_STEP)  # rotation in world axes
    return J


# ---------------------------------------------------------------------------------- 2-link arm
def test_two_link_mass_matrix_matches_mujoco_and_is_spd(two_link_torque_gravity):
    robot = two_link_torque_gravity
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v = random_state(robot, rng)
        M = robot.mass_matrix(q)
        assert M.shape == (2, 2)
        np.testing.assert_allclose(M, mujoco_mass_matrix(robot, mujoco_at(robot, q, v)), atol=1e-12)
        np.testing.assert_array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0


def test_two_link_mass_matrix_depends_on_the_elbow_only(two_link_torque_gravity):
    # Planar 2R arm: M11 = I1 + I2 + m2 l1^2 + 2 m2 l1 c2 cos(q2); it peaks at q2 = 0.
    robot = two_link_torque_gravity
    M_straight = robot.mass_matrix([0.0, 0.0])
    np.testing.assert_allclose(robot.mass_matrix([1.3, 0.0]), M_straight, atol=1e-12)
    assert robot.mass_matrix([0.0, np.pi / 2])[0, 0] < M_straight[0, 0] - 1e-3


def test_two_link_gravity_and_bias_match_mujoco(two_link_torque_gravity):
    robot = two_link_torque_gravity
    assert np.linalg.norm(robot.mj_model.opt.gravity) > 9  # the test needs gravity on
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, v = random_state(robot, rng)
        g = robot.gravity(q)
        np.testing.assert_allclose(g, mujoco_at(robot, q, np.zeros(2)).qfrc_bias, atol=1e-12)
        assert np.abs(g).max() > 0.1
        b = robot.bias(q, v)
        np.testing.assert_allclose(b, mujoco_at(robot, q, v).qfrc_bias, atol=1e-12)
        assert np.abs(b - g).max() > 1e-3  # the velocity terms are in there


def test_two_link_gravity_is_the_gradient_of_potential_energy(two_link_torque_gravity):
    robot = two_link_torque_gravity
    data = robot.pin_model.createData()
    q = np.array([0.7, -1.1])

    def potential(qq: np.ndarray) -> float:
        return float(pin.computePotentialEnergy(robot.pin_model, data, qq))

    grad = [(potential(q + h) - potential(q - h)) / (2 * FD_STEP) for h in np.eye(2) * FD_STEP]
    np.testing.assert_allclose(robot.gravity(q), grad, atol=1e-6)


def test_two_link_jacobian_and_pose_match_mujoco(two_link):
    robot = two_link
    rng = np.random.default_rng(2)
    for _ in range(5):
        q, v = random_state(robot, rng)
        d = mujoco_at(robot, q, v)
        site = robot.site_id("end_effector")
        p_WF, R_WF = robot.frame_pose("end_effector", q)
        np.testing.assert_allclose(p_WF, d.site_xpos[site], atol=1e-12)
        np.testing.assert_allclose(R_WF, d.site_xmat[site].reshape(3, 3), atol=1e-12)
        J = robot.jacobian("end_effector", q)
        assert J.shape == (6, 2)
        np.testing.assert_allclose(J, mujoco_site_jacobian(robot, q, d, "end_effector"), atol=1e-12)
        np.testing.assert_allclose(J, fd_jacobian(robot, "end_effector", q), atol=FD_ATOL)


def test_two_link_jacobian_closed_form(two_link):
    # Planar arm about z, links 0.3 m, site 0.315 m out on link 2: at q = 0 the site moves
    # along +y with speed 0.615 m/s per rad/s of the shoulder and 0.315 m/s of the elbow.
    J = two_link.jacobian("end_effector", [0.0, 0.0])
    np.testing.assert_allclose(J[:3], [[0, 0], [0.615, 0.315], [0, 0]], atol=1e-12)
    np.testing.assert_allclose(J[3:], [[0, 0], [0, 0], [1, 1]], atol=1e-12)
    p_WF, _ = two_link.frame_pose("end_effector", [0.0, 0.0])
    np.testing.assert_allclose(p_WF, [0.615, 0, 0], atol=1e-12)


# ---------------------------------------------------------------------------------- G1
def test_g1_mass_matrix_and_bias_match_mujoco(g1):
    rng = np.random.default_rng(3)
    conv = g1.converter
    for _ in range(3):
        q, v = random_state(g1, rng)
        d = mujoco_at(g1, q, v)
        M_mj = mujoco_mass_matrix(g1, d)
        M = g1.mass_matrix(q)
        assert M.shape == (g1.nv, g1.nv)
        np.testing.assert_array_equal(M, M.T)
        np.testing.assert_allclose(M, conv.mass_matrix_mj_to_pin(q, M_mj), atol=1e-10)
        np.testing.assert_allclose(g1.bias(q, v), conv.bias_mj_to_pin(q, v, M_mj, d.qfrc_bias), atol=1e-9)
        d0 = mujoco_at(g1, q, np.zeros(g1.nv))
        g = g1.gravity(q)
        np.testing.assert_allclose(g, conv.force_mj_to_pin(q, d0.qfrc_bias), atol=1e-9)
        # the base rows carry the weight: in world axes, minus the total mass times gravity
        weight_W = -float(np.sum(g1.mj_model.body_mass)) * g1.mj_model.opt.gravity
        assert weight_W[2] > 300  # [N]: the G1 weighs ~33 kg
        R_WB = pin.Quaternion(q[6], *q[3:6]).toRotationMatrix()
        np.testing.assert_allclose(R_WB @ g[:3], weight_W, atol=1e-9)


def test_g1_jacobian_and_pose_match_mujoco_and_finite_differences(g1):
    rng = np.random.default_rng(4)
    site = "imu_in_torso" if "imu_in_torso" in g1.sites else g1.sites[-1]
    for _ in range(2):
        q, v = random_state(g1, rng)
        d = mujoco_at(g1, q, v)
        p_WF, R_WF = g1.frame_pose(site, q)
        np.testing.assert_allclose(p_WF, d.site_xpos[g1.site_id(site)], atol=1e-10)
        np.testing.assert_allclose(R_WF, d.site_xmat[g1.site_id(site)].reshape(3, 3), atol=1e-10)
        J = g1.jacobian(site, q)
        assert J.shape == (6, g1.nv)
        np.testing.assert_allclose(J, mujoco_site_jacobian(g1, q, d, site), atol=1e-10)
        np.testing.assert_allclose(J, fd_jacobian(g1, site, q), atol=FD_ATOL)


def test_g1_body_pose_matches_mujoco(g1):
    q, v = random_state(g1, np.random.default_rng(5))
    d = mujoco_at(g1, q, v)
    body = "left_ankle_roll_link"
    p_WF, R_WF = g1.frame_pose(body, q)
    np.testing.assert_allclose(p_WF, d.xpos[g1.body_id(body)], atol=1e-10)
    np.testing.assert_allclose(R_WF, d.xmat[g1.body_id(body)].reshape(3, 3), atol=1e-10)


def test_g1_jacobian_references_are_related_by_the_frame_pose(g1):
    q, v = random_state(g1, np.random.default_rng(6))
    body = "left_ankle_roll_link"
    p_WF, R_WF = g1.frame_pose(body, q)
    J_wa = g1.jacobian(body, q)
    J_local = g1.jacobian(body, q, reference="local")
    J_world = g1.jacobian(body, q, reference="world")
    # local: the same twist in the frame's own axes
    np.testing.assert_allclose(J_local[:3], R_WF.T @ J_wa[:3], atol=1e-10)
    np.testing.assert_allclose(J_local[3:], R_WF.T @ J_wa[3:], atol=1e-10)
    # world: the velocity of the body point at the world origin, v_O = v_F + w x (0 - p_WF)
    np.testing.assert_allclose(J_world[3:], J_wa[3:], atol=1e-10)
    np.testing.assert_allclose(J_world[:3], J_wa[:3] + np.cross(p_WF, J_wa[3:].T).T, atol=1e-10)
    assert np.abs(J_world - J_wa).max() > 1e-2  # the references really differ here


# ---------------------------------------------------------------------------------- contract
def test_results_are_copies(two_link):
    q = np.array([0.3, 0.4])
    M = two_link.mass_matrix(q)
    p, R = two_link.frame_pose("end_effector", q)
    J = two_link.jacobian("end_effector", q)
    M_before, p_before, J_before = M.copy(), p.copy(), J.copy()
    two_link.mass_matrix([1.0, -2.0])
    two_link.frame_pose("end_effector", [1.0, -2.0])
    two_link.jacobian("end_effector", [1.0, -2.0])
    np.testing.assert_array_equal(M, M_before)
    np.testing.assert_array_equal(p, p_before)
    np.testing.assert_array_equal(J, J_before)
    M[0, 0] = 123.0
    assert two_link.mass_matrix(q)[0, 0] != 123.0


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda r: r.mass_matrix([0.1, 0.2, 0.3]), r"q must have shape \(2,\); got shape \(3,\)"),
        (lambda r: r.gravity([0.1, np.nan]), r"q must be finite; entries \[1\] are \[nan\]"),
        (lambda r: r.bias([0.1, 0.2], [np.inf, 0.0]), r"v must be finite; entries \[0\] are \[inf\]"),
        (lambda r: r.bias([0.1, 0.2], [0.0]), r"v must have shape \(2,\); got shape \(1,\)"),
        (lambda r: r.jacobian("end_effector", [[0.1, 0.2]]), r"q must have shape \(2,\)"),
        (lambda r: r.frame_pose("end_effector", "ab"), "q must be a numeric vector of shape"),
    ],
)
def test_bad_states_raise_state_error(two_link, call, message):
    with pytest.raises(StateError, match=message):
        call(two_link)


def test_unknown_frame_suggests_close_names(two_link):
    with pytest.raises(UnknownNameError, match="Unknown frame 'end_efector'") as info:
        two_link.frame_pose("end_efector", [0.0, 0.0])
    assert info.value.suggestions[0] == "end_effector"
    with pytest.raises(UnknownNameError, match="Did you mean 'end_effector'"):
        two_link.jacobian("end_efector", [0.0, 0.0])


def test_unknown_jacobian_reference_lists_the_choices(two_link):
    with pytest.raises(UnknownNameError, match="Available: world_aligned, local, world") as info:
        two_link.jacobian("end_effector", [0.0, 0.0], reference="world_algned")
    assert info.value.suggestions[0] == "world_aligned"


# ---------------------------------------------------------------------------------- finite differences
@pytest.mark.parametrize("name", ["two_link_torque_gravity", "g1"])
def test_mass_matrix_bias_and_gravity_against_finite_differences(name, request):
    """Along a motion with velocity v, ``v^T (b - g) = 1/2 v^T (dM/dt) v`` (the power balance:
    the velocity terms do no net work beyond the change of M), and ``g = dV/dq``; dM/dt and dV/dq
    by central differences on the manifold (``pin.integrate``), so the G1's base rows count too."""
    robot: Robot = request.getfixturevalue(name)
    model = robot.pin_model
    data = model.createData()
    rng = np.random.default_rng(8)

    def step(q: np.ndarray, dv: np.ndarray) -> np.ndarray:
        return pin.integrate(model, q, dv)

    for _ in range(3):
        q, v = random_state(robot, rng)
        dM = (robot.mass_matrix(step(q, FD_STEP * v)) - robot.mass_matrix(step(q, -FD_STEP * v))) / (
            2 * FD_STEP
        )
        power = float(v @ (robot.bias(q, v) - robot.gravity(q)))
        half_rate = 0.5 * float(v @ dM @ v)
        assert abs(half_rate) > 1e-5  # the check has something to see (2-link: ~1e-4 W)
        assert power == pytest.approx(half_rate, rel=1e-6)
        grad = np.array([
            (pin.computePotentialEnergy(model, data, step(q, FD_STEP * e))
             - pin.computePotentialEnergy(model, data, step(q, -FD_STEP * e))) / (2 * FD_STEP)
            for e in np.eye(robot.nv)
        ])
        np.testing.assert_allclose(robot.gravity(q), grad, rtol=0, atol=1e-5 * max(1.0, np.abs(grad).max()))


def test_plant_mass_scaling_and_payload_in_both_engines(two_link_torque_gravity):
    import numpy as np

    from mbctl.robots.edits import add_payload, scale_link_masses

    heavy = scale_link_masses(two_link_torque_gravity, 1.25)
    for b, name in zip(heavy.robot_body_ids, heavy.bodies, strict=True):
        nominal = two_link_torque_gravity.mj_model.body_mass[two_link_torque_gravity.body_id(name)]
        assert heavy.mj_model.body_mass[b] == 1.25 * nominal
    np.testing.assert_allclose(heavy.mj_model.body_inertia[heavy.body_id("link2")],
                               1.25 * two_link_torque_gravity.mj_model.body_inertia[
                                   two_link_torque_gravity.body_id("link2")])
    loaded = add_payload(two_link_torque_gravity, 0.5, "link2", (0.1, 0.02, 0.0))
    assert "payload_link2" in loaded.bodies
    q = np.array([0.3, -0.4])
    g0, g1 = two_link_torque_gravity.gravity(q), loaded.gravity(q)  # the model pair's own check passed
    assert not np.allclose(g0, g1)


def test_standalone_xml_loads_from_any_folder(two_link_torque, tmp_path, monkeypatch):
    from mbctl.robots.edits import add_payload, standalone_xml
    from mbctl.robots.registry import load_robot

    path = tmp_path / "elsewhere" / "model.xml"
    path.parent.mkdir()
    path.write_text(standalone_xml(add_payload(two_link_torque, 0.2, "ee_body")))  # payload at the origin
    monkeypatch.chdir(tmp_path)
    robot = load_robot(path)
    assert robot.mj_model.body_mass[robot.body_id("payload_ee_body")] == 0.2  # its inertial survived


def test_the_fall_rule_names_each_other_body_on_the_floor_once_sorted():
    from mbctl.robots.g1 import FallRule

    rule = FallRule(0.3, ("left_foot", "right_foot"), "pelvis")
    assert rule.reason(0.7, ()) is None
    assert rule.reason(0.7, ("right_foot", "left_foot")) is None
    assert rule.reason(0.7, ("torso", "left_foot", "knee", "torso")) == "knee, torso touched the floor"
    assert rule.reason(0.29, ("left_foot",)) == "pelvis at 0.290 m (below 0.3 m)"
