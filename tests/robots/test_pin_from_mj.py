"""pin_model_from_mj: the Pinocchio model built from MuJoCo's compiled model matches MuJoCo.

Each robot is an MJCF string with one feature Pinocchio's MJCF parser gets wrong or misses. At
random configurations the built model must reproduce MuJoCo's body and site poses, mass matrix,
gravity forces and site Jacobians (after the free-flyer convention conversion), and its mass.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import ModelMismatchError
from mbctl.robots.conventions import JointLayout, StateConverter
from mbctl.robots.pin_from_mj import articulated_bodies, pin_model_from_mj

FK_ATOL = 1e-9  # [m] and rotation-matrix entries
DYN_ATOL = 1e-9  # [kg m^2], [kg], [N m], [N]

_KIND = {
    mujoco.mjtJoint.mjJNT_FREE: ("free", 7, 6),
    mujoco.mjtJoint.mjJNT_BALL: ("ball", 4, 3),
    mujoco.mjtJoint.mjJNT_HINGE: ("hinge", 1, 1),
    mujoco.mjtJoint.mjJNT_SLIDE: ("slide", 1, 1),
}


def converter_of(m: mujoco.MjModel) -> StateConverter:
    layouts = []
    for j in range(m.njnt):
        kind, nq, nv = _KIND[mujoco.mjtJoint(int(m.jnt_type[j]))]
        adr_q, adr_v = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
        layouts.append(JointLayout(m.joint(j).name, kind, adr_q, adr_v, nq, nv))
    return StateConverter(layouts, m.nq, m.nv)


def random_qpos(m: mujoco.MjModel, rng: np.random.Generator) -> np.ndarray:
    """A random MuJoCo qpos (nq,): unit quaternions, angles and positions within limits."""
    qpos = np.zeros(m.nq)
    for j in range(m.njnt):
        adr = int(m.jnt_qposadr[j])
        kind = _KIND[mujoco.mjtJoint(int(m.jnt_type[j]))][0]
        if kind in ("free", "ball"):
            at = adr + 3 if kind == "free" else adr
            qpos[adr:at] = rng.uniform(-1.0, 1.0, at - adr)
            quat = rng.normal(size=4)
            qpos[at : at + 4] = quat / np.linalg.norm(quat)
        elif m.jnt_limited[j]:
            qpos[adr] = rng.uniform(*m.jnt_range[j])
        else:
            qpos[adr] = rng.uniform(-2.0, 2.0)
    return qpos


def check_against_mujoco(m: mujoco.MjModel, pm: pin.Model, n: int = 4, seed: int = 0) -> None:
    """FK of every body and site, M, gravity, site Jacobians and mass agree with MuJoCo."""
    assert (pm.nq, pm.nv) == (m.nq, m.nv)
    assert list(pm.names)[1:] == [m.joint(j).name or f"joint{j}" for j in range(m.njnt)]
    total_mass = sum(inertia.mass for inertia in pm.inertias)
    assert total_mass == pytest.approx(float(np.sum(m.body_mass)), rel=1e-12)
    np.testing.assert_array_equal(pm.armature, m.dof_armature)
    np.testing.assert_array_equal(pm.gravity.linear, m.opt.gravity)
    conv = converter_of(m)
    d = mujoco.MjData(m)
    pd = pm.createData()
    rng = np.random.default_rng(seed)
    body_frames = [pm.getFrameId(m.body(b).name, pin.FrameType.BODY) for b in range(1, m.nbody)]
    site_frames = [pm.getFrameId(m.site(s).name, pin.FrameType.OP_FRAME) for s in range(m.nsite)]
    for _ in range(n):
        qpos = random_qpos(m, rng)
        d.qpos[:] = qpos
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        q = conv.q_mj_to_pin(qpos)
        pin.framesForwardKinematics(pm, pd, q)
        for b, f in enumerate(body_frames, start=1):
            X_WB = pd.oMf[f]
            np.testing.assert_allclose(X_WB.translation, d.xpos[b], atol=FK_ATOL, err_msg=m.body(b).name)
            np.testing.assert_allclose(X_WB.rotation, d.xmat[b].reshape(3, 3), atol=FK_ATOL)
        for s, f in enumerate(site_frames):
            X_WS = pd.oMf[f]
            np.testing.assert_allclose(X_WS.translation, d.site_xpos[s], atol=FK_ATOL, err_msg=m.site(s).name)
            np.testing.assert_allclose(X_WS.rotation, d.site_xmat[s].reshape(3, 3), atol=FK_ATOL)
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        M_pin = pin.crba(pm, pd, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        np.testing.assert_allclose(conv.mass_matrix_mj_to_pin(q, M_mj), M_pin, atol=DYN_ATOL)
        # at zero velocity qfrc_bias is gravity alone, and the velocity-frame term vanishes
        g_pin = pin.computeGeneralizedGravity(pm, pd, q)
        np.testing.assert_allclose(conv.force_mj_to_pin(q, d.qfrc_bias), g_pin, atol=DYN_ATOL)
        T = conv.velocity_map(q)
        for s, f in enumerate(site_frames):
            jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
            mujoco.mj_jacSite(m, d, jacp, jacr, s)
            J = pin.computeFrameJacobian(pm, pd, q, f, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            J = np.reshape(J, (6, m.nv))  # eigenpy returns a (6, 1) matrix as a (6,) vector
            np.testing.assert_allclose(J, np.vstack([jacp, jacr]) @ T, atol=DYN_ATOL)


def check_fixed_base_directly(m: mujoco.MjModel, pm: pin.Model, seed: int = 1) -> None:
    """Without free joints M and the gravity forces match MuJoCo's with no conversion at all."""
    d = mujoco.MjData(m)
    pd = pm.createData()
    rng = np.random.default_rng(seed)
    for _ in range(3):
        qpos = random_qpos(m, rng)
        d.qpos[:] = qpos
        mujoco.mj_forward(m, d)
        q = converter_of(m).q_mj_to_pin(qpos)  # ball quaternions only
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        M_pin = pin.crba(pm, pd, q)
        np.testing.assert_allclose(np.triu(M_pin) + np.triu(M_pin, 1).T, M_mj, atol=DYN_ATOL)
        np.testing.assert_allclose(pin.computeGeneralizedGravity(pm, pd, q), d.qfrc_bias, atol=DYN_ATOL)


def build(xml: str) -> tuple[mujoco.MjModel, pin.Model]:
    m = mujoco.MjModel.from_xml_string(xml)
    return m, pin_model_from_mj(m)


# A two-link arm body (with a tool site) to hang under the feature being tested.
ARM = """
<body name="upper" pos="0 0 0.1">
  <joint name="shoulder" axis="0 1 0" armature="0.02" damping="0.5" frictionloss="0.1"
         range="-2 2" limited="true" actuatorfrcrange="-30 40" actuatorfrclimited="true"/>
  <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1.2"/>
  <body name="fore" pos="0.3 0 0">
    <joint name="elbow" axis="0 1 0" armature="0.01"/>
    <geom type="box" size="0.12 0.02 0.02" pos="0.12 0 0.01" euler="5 10 15" mass="0.7"/>
    <site name="tool" pos="0.25 0 0" euler="0 90 0"/>
  </body>
</body>
"""


def test_rotated_jointless_root_body():
    """A jointless mount body, shifted and rotated, under the world: the parser drops its pose."""
    m, pm = build(f"""<mujoco><worldbody>
      <body name="mount" pos="0.4 -0.2 1.1" euler="30 -20 70">
        <geom type="cylinder" size="0.05 0.05" mass="3"/>{ARM}
      </body></worldbody></mujoco>""")
    check_against_mujoco(m, pm)
    check_fixed_base_directly(m, pm)
    mount = pm.frames[pm.getFrameId("mount", pin.FrameType.BODY)]
    assert mount.parentJoint == 0
    assert pm.frames[pm.getFrameId("mount_fixed")].type == pin.FrameType.FIXED_JOINT


def test_site_pose_from_default_class():
    m, pm = build(f"""<mujoco>
      <default><default class="marker"><site pos="0.05 0.02 -0.01" euler="10 20 30"/></default></default>
      <worldbody><body name="mount">{ARM}<site name="marked" class="marker"/></body></worldbody>
    </mujoco>""")
    np.testing.assert_allclose(m.site("marked").pos, [0.05, 0.02, -0.01])
    check_against_mujoco(m, pm)


def test_site_inside_frame():
    m, pm = build(f"""<mujoco><worldbody><body name="mount">{ARM}
      <frame pos="0.1 0 0.2" euler="0 45 0"><site name="framed" pos="0.1 0 0" euler="90 0 0"/></frame>
    </body></worldbody></mujoco>""")
    assert pm.existFrame("framed", pin.FrameType.OP_FRAME)
    check_against_mujoco(m, pm)


def test_mobile_base_with_three_joints_in_one_body():
    """slide x + slide y + hinge z in one body: a chain of three joints, not one composite."""
    m, pm = build(f"""<mujoco><worldbody>
      <body name="base" pos="0 0 0.2" euler="0 0 15">
        <joint name="base_x" type="slide" axis="1 0 0"/>
        <joint name="base_y" type="slide" axis="0 1 0"/>
        <joint name="base_yaw" axis="0 0 1" pos="0.05 0.02 0"/>
        <geom type="box" size="0.3 0.2 0.1" pos="0.02 0 0" mass="20"/>
        <site name="base_site" pos="0.2 0.1 0.1"/>{ARM}
      </body></worldbody></mujoco>""")
    assert [pm.joints[i].shortname() for i in range(1, 4)] == ["JointModelPX", "JointModelPY", "JointModelRZ"]
    check_against_mujoco(m, pm)
    check_fixed_base_directly(m, pm)
    # the first two joints carry no mass: the whole base hangs from base_yaw
    assert pm.inertias[1].mass == 0.0 and pm.inertias[2].mass == 0.0
    assert pm.inertias[3].mass == pytest.approx(20.0)


def test_two_separate_trees():
    """Two arms under the world: the parser reads only the first tree."""
    second = ARM.replace('name="', 'name="b_')
    m, pm = build(f"""<mujoco><worldbody>
      <body name="mount_a" pos="-0.5 0 0">{ARM}</body>
      <body name="mount_b" pos="0.5 0 0" euler="0 0 180">{second}</body>
    </worldbody></mujoco>""")
    assert pm.nv == 4
    check_against_mujoco(m, pm)
    check_fixed_base_directly(m, pm)


def test_ball_joints():
    m, pm = build("""<mujoco><worldbody>
      <body name="torso" pos="0 0 1">
        <geom size="0.1" mass="2"/>
        <body name="arm" pos="0.1 0 0" euler="0 30 0">
          <joint name="shoulder" type="ball" pos="0.02 0.01 0" armature="0.03"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
          <body name="hand" pos="0.3 0 0">
            <joint name="wrist" type="ball"/>
            <geom type="box" size="0.05 0.03 0.01" pos="0.05 0 0" mass="0.3"/>
            <site name="palm" pos="0.08 0 0"/>
          </body>
        </body>
      </body></worldbody></mujoco>""")
    assert pm.nq == 8 and pm.nv == 6
    check_against_mujoco(m, pm)
    check_fixed_base_directly(m, pm)


def test_unaligned_hinge_axes_with_anchor_offsets():
    """Hinges about oblique axes through points away from the body origin (and a slide)."""
    m, pm = build("""<mujoco><worldbody>
      <body name="l1" pos="0.1 0.2 0.3" quat="0.9 0.1 -0.2 0.3">
        <joint name="h1" axis="0.3 -0.5 1" pos="0.05 -0.02 0.03"/>
        <geom type="box" size="0.2 0.03 0.03" pos="0.1 0 0" mass="1.5"/>
        <body name="l2" pos="0.2 0 0" euler="10 20 30">
          <joint name="h2" axis="1 1 0" pos="-0.04 0.06 0.01" range="-1 1.5" limited="true"/>
          <joint name="s2" type="slide" axis="0 -1 1" pos="0.3 0.3 0.3"/>
          <geom type="ellipsoid" size="0.1 0.04 0.03" pos="0.05 0.01 0" euler="40 0 10" mass="0.8"/>
          <site name="tip" pos="0.15 0 0.02" euler="5 6 7"/>
        </body>
      </body></worldbody></mujoco>""")
    assert [pm.joints[i].shortname() for i in range(1, 4)] == [
        "JointModelRevoluteUnaligned", "JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"
    ]
    check_against_mujoco(m, pm)
    check_fixed_base_directly(m, pm)


def test_single_dof():
    m, pm = build("""<mujoco><worldbody>
      <body name="pendulum" pos="0 0 1" euler="90 0 0">
        <joint name="pivot" axis="0 0 -1"/>
        <geom type="capsule" fromto="0 0 0 0 -0.5 0" size="0.02" mass="1"/>
        <site name="bob" pos="0 -0.5 0"/>
      </body></worldbody></mujoco>""")
    assert pm.nv == 1
    check_against_mujoco(m, pm)
    check_fixed_base_directly(m, pm)


def test_robot_from_an_include(tmp_path):
    """A scene that <include>s the robot file (the parser cannot follow the include)."""
    (tmp_path / "arm.xml").write_text(f"""<mujoco><worldbody>
      <body name="mount" pos="0 0 0.5" euler="0 0 45">{ARM}</body></worldbody></mujoco>""")
    (tmp_path / "scene.xml").write_text("""<mujoco><include file="arm.xml"/>
      <worldbody><geom name="floor" type="plane" size="2 2 0.1"/></worldbody></mujoco>""")
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "scene.xml"))
    pm = pin_model_from_mj(m)
    assert list(pm.names)[1:] == ["shoulder", "elbow"]
    check_against_mujoco(m, pm)


FLOATING = """<mujoco>
  <compiler angle="radian"/>
  <option gravity="0.5 -0.3 -9.81"/>
  <worldbody>
    <body name="table" pos="1 0 0.4" euler="0 0 0.3"><geom type="box" size="0.3 0.3 0.02" mass="10"/></body>
    <body name="target" mocap="true" pos="0 1 1"><site name="target_site"/></body>
    <body name="trunk" pos="0 0 0.8" euler="0.2 0 0">
      <freejoint/>
      <geom type="box" size="0.2 0.1 0.05" pos="0.01 0 0" mass="8"/>
      <site name="imu" pos="0.05 0 0.02" euler="0 0 1.5"/>
      <body name="leg" pos="0 0.1 -0.05">
        <joint name="hip" axis="0 1 0" pos="0 0 0.02" armature="0.05" range="-1 1" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="1"/>
        <body name="shin" pos="0 0 -0.3">
          <joint name="knee" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="0.8"/>
          <site name="foot" pos="0 0 -0.3"/>
        </body>
      </body>
    </body>
  </worldbody>
  <keyframe><key name="crouch" qpos="0.1 0.2 0.7 0.9 0 0.1 0 0.5 -1"/></keyframe>
</mujoco>"""


def test_free_floating_base_with_scenery():
    m, pm = build(FLOATING)
    assert pm.joints[1].shortname() == "JointModelFreeFlyer"
    assert list(pm.names)[1:] == ["joint0", "hip", "knee"]  # the unnamed free joint gets its id
    check_against_mujoco(m, pm)


def test_free_floating_base_without_scenery():
    """``articulated_bodies`` leaves out the static table and the mocap target."""
    m = mujoco.MjModel.from_xml_string(FLOATING)
    robot = articulated_bodies(m)
    assert {m.body(b).name for b in robot} == {"trunk", "leg", "shin"}
    pm = pin_model_from_mj(m, robot)
    assert (pm.nq, pm.nv) == (m.nq, m.nv)
    assert not pm.existFrame("table") and not pm.existFrame("target_site")
    assert sum(i.mass for i in pm.inertias) == pytest.approx(9.8)
    conv = converter_of(m)
    d, pd = mujoco.MjData(m), pm.createData()
    d.qpos[:] = random_qpos(m, np.random.default_rng(3))
    mujoco.mj_forward(m, d)
    q = conv.q_mj_to_pin(d.qpos)
    pin.framesForwardKinematics(pm, pd, q)
    for name in ("trunk", "leg", "shin"):
        np.testing.assert_allclose(pd.oMf[pm.getFrameId(name)].translation, d.body(name).xpos, atol=FK_ATOL)
    np.testing.assert_allclose(pd.oMf[pm.getFrameId("foot")].translation, d.site("foot").xpos, atol=FK_ATOL)


def test_joint_data_and_reference_configurations():
    m, pm = build(FLOATING)
    hip, knee = pm.joints[pm.getJointId("hip")], pm.joints[pm.getJointId("knee")]
    np.testing.assert_array_equal(pm.lowerPositionLimit[[hip.idx_q, knee.idx_q]], [-1.0, -np.inf])
    np.testing.assert_array_equal(pm.upperPositionLimit[[hip.idx_q, knee.idx_q]], [1.0, np.inf])
    np.testing.assert_array_equal(pm.armature, [0, 0, 0, 0, 0, 0, 0.05, 0])
    crouch = pm.referenceConfigurations["crouch"]  # MuJoCo normalized the keyframe's quaternion
    norm = np.hypot(0.9, 0.1)
    np.testing.assert_allclose(crouch, [0.1, 0.2, 0.7, 0, 0.1 / norm, 0, 0.9 / norm, 0.5, -1])
    np.testing.assert_array_equal(pm.referenceConfigurations["qpos0"], converter_of(m).q_mj_to_pin(m.qpos0))

    m, pm = build(f"<mujoco><worldbody><body name='mount'>{ARM}</body></worldbody></mujoco>")
    np.testing.assert_array_equal(pm.damping, [0.5, 0.0])
    np.testing.assert_array_equal(pm.upperDryFrictionLimit, [0.1, 0.0])
    np.testing.assert_array_equal(pm.lowerDryFrictionLimit, [-0.1, 0.0])
    np.testing.assert_array_equal(pm.lowerEffortLimit, [-30.0, -np.inf])
    np.testing.assert_array_equal(pm.upperEffortLimit, [40.0, np.inf])


def test_g1(g1):
    """The Menagerie G1 scene: every body and site pose, and M to 1e-9 relative."""
    m = g1.mj_model
    pm = pin_model_from_mj(m)
    assert list(pm.names)[1:] == list(g1.joints)
    assert sum(i.mass for i in pm.inertias) == pytest.approx(float(np.sum(m.body_mass)), rel=1e-12)
    conv = g1.converter
    d, pd = mujoco.MjData(m), pm.createData()
    rng = np.random.default_rng(4)
    for _ in range(3):
        d.qpos[:] = random_qpos(m, rng)
        mujoco.mj_forward(m, d)
        q = conv.q_mj_to_pin(d.qpos)
        pin.framesForwardKinematics(pm, pd, q)
        for b in range(1, m.nbody):
            X_WB = pd.oMf[pm.getFrameId(m.body(b).name, pin.FrameType.BODY)]
            np.testing.assert_allclose(X_WB.translation, d.xpos[b], atol=FK_ATOL)
            np.testing.assert_allclose(X_WB.rotation, d.xmat[b].reshape(3, 3), atol=FK_ATOL)
        for s in range(m.nsite):
            X_WS = pd.oMf[pm.getFrameId(m.site(s).name, pin.FrameType.OP_FRAME)]
            np.testing.assert_allclose(X_WS.translation, d.site_xpos[s], atol=FK_ATOL)
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        M_pin = pin.crba(pm, pd, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        M_conv = conv.mass_matrix_mj_to_pin(q, M_mj)
        assert np.max(np.abs(M_conv - M_pin)) <= 1e-9 * np.max(np.abs(M_pin))


def test_nonzero_joint_reference_is_rejected():
    m = mujoco.MjModel.from_xml_string("""<mujoco><compiler angle="radian"/><worldbody><body name="b">
      <joint name="offset_hinge" axis="0 0 1" ref="0.3"/><geom size="0.1" mass="1"/>
    </body></worldbody></mujoco>""")
    with pytest.raises(ModelMismatchError, match=r"'offset_hinge' has reference position ref=0\.3"):
        pin_model_from_mj(m)


def test_bad_body_subsets_are_rejected():
    m, _ = build(f"<mujoco><worldbody><body name='mount'>{ARM}</body></worldbody></mujoco>")
    with pytest.raises(ModelMismatchError, match=r"missing the parents of upper \(parent mount\)"):
        pin_model_from_mj(m, {m.body("upper").id, m.body("fore").id})
    with pytest.raises(ModelMismatchError, match=r"ids \[17\] that are not bodies"):
        pin_model_from_mj(m, {1, 17})
