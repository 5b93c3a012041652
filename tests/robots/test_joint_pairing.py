"""A URDF against its MJCF: joints paired by name, renamed by a joint map, a free flyer added.

One small floating-base robot (a trunk with two legs and a head on a continuous neck) is written
both as MJCF and as URDF from the same table, so the two agree to round-off; each test then
changes one thing in the URDF: the joint order, the names, the base, a mass.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import JointMapError, UnknownNameError, load_robot
from mbctl.robots.crosscheck import crosscheck
from mbctl.robots.joint_pairing import pair_joints, parse_joint_map
from tests.conftest import run_mbctl

# (link, parent link, joint, joint type, axis, origin [m], mass [kg], CoM [m], principal inertia [kg m^2]),
# in the MJCF's order: the rear leg first. Pinocchio's URDF parser orders a link's children by name,
# so it lists the front leg first, as Go1's URDF and MJCF differ.
LINKS = [
    ("RR_thigh", "trunk", "RR_hip", "revolute", (0, 1, 0), (-0.2, -0.1, 0), 1.0, (0, -0.01, -0.1),
     (0.01, 0.012, 0.002)),
    ("RR_calf", "RR_thigh", "RR_knee", "revolute", (0, 0.6, 0.8), (0, 0, -0.2), 0.3, (0, 0, -0.1),
     (3e-3, 3e-3, 3e-4)),
    ("FL_thigh", "trunk", "FL_hip", "revolute", (0, 1, 0), (0.2, 0.1, 0), 1.0, (0, 0.01, -0.1),
     (0.01, 0.012, 0.002)),
    ("FL_calf", "FL_thigh", "FL_knee", "revolute", (0, 1, 0), (0, 0, -0.2), 0.3, (0, 0, -0.1),
     (3e-3, 3e-3, 3e-4)),
    ("head", "trunk", "neck", "continuous", (0, 0, 1), (0.25, 0, 0.1), 1.1, (0.05, 0, 0.02),
     (2e-3, 3e-3, 3e-3)),
]
TRUNK = ("trunk", 8.0, (0.01, 0, 0), (0.05, 0.2, 0.2))


def _v(x) -> str:
    return " ".join(str(float(c)) for c in x)


def mjcf() -> str:
    """The robot as MJCF, joints in the order FL, RR, neck; a free joint on the trunk."""
    children: dict[str, list] = {}
    for row in LINKS:
        children.setdefault(row[1], []).append(row)

    def body(row) -> str:
        link, _, joint, kind, axis, origin, mass, com, inertia = row
        rng = ' range="-2 2"' if kind == "revolute" else ""
        inner = "".join(body(c) for c in children.get(link, []))
        return (f'<body name="{link}" pos="{_v(origin)}"><joint name="{joint}" axis="{_v(axis)}"{rng}/>'
                f'<inertial pos="{_v(com)}" mass="{mass}" diaginertia="{_v(inertia)}"/>{inner}</body>')

    name, mass, com, inertia = TRUNK
    return (f'<mujoco model="dog"><compiler angle="radian" autolimits="true"/><worldbody>'
            f'<body name="{name}" pos="0 0 0.5"><freejoint name="floating_base"/>'
            f'<inertial pos="{_v(com)}" mass="{mass}" diaginertia="{_v(inertia)}"/>'
            + "".join(body(c) for c in children[name]) + "</body></worldbody></mujoco>")


def urdf(rename=None, masses=None) -> str:
    """The robot as a fixed-base URDF; ``rename`` maps joint and link names, ``masses`` link masses."""
    rename, masses = rename or {}, masses or {}

    def link(name, mass, com, inertia) -> str:
        ixx, iyy, izz = inertia
        return (f'<link name="{rename.get(name, name)}"><inertial><origin xyz="{_v(com)}"/>'
                f'<mass value="{masses.get(name, mass)}"/>'
                f'<inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial></link>')

    text = '<?xml version="1.0"?><robot name="dog">' + link(*TRUNK)
    for child, parent, joint, kind, axis, origin, mass, com, inertia in LINKS:
        limit = '<limit lower="-2" upper="2" effort="10" velocity="10"/>' if kind == "revolute" else ""
        text += (f'<joint name="{rename.get(joint, joint)}" type="{kind}">'
                 f'<parent link="{rename.get(parent, parent)}"/><child link="{rename.get(child, child)}"/>'
                 f'<origin xyz="{_v(origin)}"/><axis xyz="{_v(axis)}"/>{limit}</joint>'
                 + link(child, mass, com, inertia))
    return text + "</robot>"


@pytest.fixture
def files(tmp_path):
    def write(**kwargs) -> tuple[Path, Path]:
        (tmp_path / "dog.xml").write_text(mjcf())
        (tmp_path / "dog.urdf").write_text(urdf(**kwargs))
        return tmp_path / "dog.xml", tmp_path / "dog.urdf"

    return write


def _clean(report, bound: float = 1e-12) -> None:
    assert report.passed and report.complete, report.to_text()
    for q in report.quantities:
        assert q.max_rel_error <= bound, q


def test_urdf_in_another_order_fixed_base_continuous_neck_pairs_by_name(files):
    robot_file, urdf_file = files()
    parsed = pin.buildModelFromUrdf(str(urdf_file))
    assert list(parsed.names)[1:] == ["FL_hip", "FL_knee", "RR_hip", "RR_knee", "neck"]  # not MuJoCo's order
    assert parsed.nq == 6  # the continuous neck has nq 2 (cos, sin); fixed base
    robot = load_robot(robot_file, pin_model_file=urdf_file, check=False)
    assert list(robot.pin_model.names)[1:] == list(robot.joints)
    report = crosscheck(robot, n_states=30, seed=1)
    _clean(report)
    assert report.edits[1:] == (
        "free flyer 'floating_base' added at 'trunk' (the Pinocchio model is fixed-base; the plant's "
        "'trunk' has a free joint)",
        "joints put in the plant's order (first moved: 'RR_hip' to position 0)",
        "continuous joints made revolute without limits (nq 1, as MuJoCo's hinges): neck",
    )
    text = report.to_text()
    assert "load-time edits:\n  - Pinocchio model from" in text and "free flyer 'floating_base' added" in text
    assert report.notes == ()  # the models agree everywhere: nothing located
    load_robot(robot_file, pin_model_file=urdf_file)  # the load-time agreement check passes too


def test_fixed_base_kept_on_request_fails_structure_with_a_hint(files):
    robot_file, urdf_file = files()
    report = crosscheck(load_robot(robot_file, pin_model_file=urdf_file, check=False, floating_base=False),
                        n_states=5)
    assert report.failed == ("structure",)
    why = report.quantity("structure").note
    assert "joints do not pair by name (Pinocchio 5, MuJoCo 6 joints); only in MuJoCo: floating_base" in why
    assert "add a free flyer with --floating-base" in why


def test_renamed_joints_fail_structure_listing_both_sides_until_mapped(files, tmp_path):
    rename = {"FL_hip": "fl_hip_joint", "FL_knee": "fl_knee_joint", "FL_thigh": "fl_thigh_link"}
    robot_file, urdf_file = files(rename=rename)
    report = crosscheck(load_robot(robot_file, pin_model_file=urdf_file, check=False), n_states=5)
    assert report.failed == ("structure",)
    why = report.quantity("structure").note
    assert ("joints do not pair by name (Pinocchio 6, MuJoCo 6 joints); only in MuJoCo: FL_hip, FL_knee; "
            "only in Pinocchio: fl_hip_joint, fl_knee_joint") in why
    assert "--joint-map" in why
    # mapped, from a dict and from a file of A=B lines with comments
    joint_map = {"fl_hip_joint": "FL_hip", "fl_knee_joint": "FL_knee"}
    (tmp_path / "map.txt").write_text("# URDF = MJCF\nfl_hip_joint = FL_hip\n\nfl_knee_joint=FL_knee # k\n")
    inline = parse_joint_map("fl_hip_joint=FL_hip, fl_knee_joint=FL_knee")
    assert parse_joint_map(str(tmp_path / "map.txt")) == joint_map == inline
    robot = load_robot(robot_file, pin_model_file=urdf_file, check=False, joint_map=joint_map)
    report = crosscheck(robot, n_states=30, seed=2)
    _clean(report)
    assert "joints renamed: fl_hip_joint -> FL_hip, fl_knee_joint -> FL_knee" in report.edits
    # the renamed joint's link takes the plant's body name, so its kinematics are compared
    assert "bodies of renamed joints named as the plant's: fl_thigh_link -> FL_thigh" in report.edits
    assert not any("no Pinocchio frame" in n for n in report.notes)


def test_a_wrong_joint_map_fails_structure_naming_the_tree(files):
    robot_file, urdf_file = files()
    swapped = {"FL_hip": "RR_hip", "RR_hip": "FL_hip"}  # thumb for middle finger, as a careless map would
    report = crosscheck(load_robot(robot_file, pin_model_file=urdf_file, check=False, joint_map=swapped),
                        n_states=5)
    assert report.failed == ("structure",)
    assert ("joint 'RR_knee': parent 'FL_hip' in Pinocchio, 'RR_hip' in MuJoCo (the trees differ)"
            in report.quantity("structure").note)


def test_a_mass_difference_is_located_with_both_values(files):
    robot_file, urdf_file = files(masses={"head": 1.2})
    report = crosscheck(load_robot(robot_file, pin_model_file=urdf_file, check=False), n_states=20)
    assert {"mass_matrix", "gravity", "com"} <= set(report.failed)
    located = next(n for n in report.notes if n.startswith("the models differ"))
    assert "head (joint 'neck'): mass 1.2 vs 1.1 kg" in located
    assert "robot mass differs: Pinocchio 11.8 kg, MuJoCo 11.7 kg" in " ".join(report.notes)


@pytest.mark.parametrize(
    ("text", "error", "match"),
    [
        ("a", JointMapError, r"'a' is not PIN_JOINT=PLANT_JOINT"),
        ("a=b,a=c", JointMapError, "joint 'a' is mapped twice"),
        ("a=c,b=c", JointMapError, "plant joint 'c' is the target of two joints"),
    ],
)
def test_malformed_joint_maps_are_named(text, error, match):
    with pytest.raises(error, match=match):
        parse_joint_map(text)


def test_joint_map_names_must_exist_on_their_side(files):
    robot_file, urdf_file = files()
    with pytest.raises(UnknownNameError, match="Unknown joint of the Pinocchio model .* 'FL_hipp'"):
        load_robot(robot_file, pin_model_file=urdf_file, joint_map={"FL_hipp": "FL_hip"})
    with pytest.raises(UnknownNameError, match="Unknown joint of the plant .* 'FL_hop'"):
        load_robot(robot_file, pin_model_file=urdf_file, joint_map={"FL_hip": "FL_hop"})


def test_pairing_an_agreeing_model_changes_nothing(files):
    robot_file, _ = files()
    robot = load_robot(robot_file)
    same = pair_joints(robot.pin_model, robot.pin_model)
    assert same.model is robot.pin_model and same.edits == ()
    np.testing.assert_array_equal(same.model.armature, robot.pin_model.armature)


def test_cli_joint_map_and_floating_base(files, tmp_path):
    robot_file, urdf_file = files(rename={"neck": "head_yaw"})
    base = ("xcheck", str(robot_file), "--pin-model", str(urdf_file), "--states", "10", "--quiet")
    out = run_mbctl(*base, "--joint-map", "head_yaw=neck", "--output", str(tmp_path / "a"))
    assert out.returncode == 0, out.stdout + out.stderr
    assert "  - joints renamed: head_yaw -> neck" in out.stdout and "result: PASS" in out.stdout
    out = run_mbctl(*base, "--output", str(tmp_path / "b"))
    assert out.returncode == 1 and "only in Pinocchio: head_yaw" in out.stdout
    out = run_mbctl(*base, "--joint-map", "head_yaw=nek", "--output", str(tmp_path / "c"))
    assert out.returncode == 2 and "Did you mean 'neck'" in out.stderr
    out = run_mbctl(*base, "--joint-map", "head_yaw=neck", "--fixed-base", "--output", str(tmp_path / "d"))
    assert out.returncode == 1 and "--floating-base" in out.stdout
    out = run_mbctl("xcheck", str(robot_file), "--joint-map", "a=b", "--output", str(tmp_path / "e"))
    assert out.returncode == 2 and "use them with pin_model_file (--pin-model)" in out.stderr


def test_unnamed_mujoco_joints_pair_through_their_bodies(tmp_path):
    # Pinocchio's MJCF parser invents names ("b_free", "cJoint_0"), the plant calls them joint<id>.
    path = tmp_path / "unnamed.xml"
    path.write_text('<mujoco><worldbody><body name="b" pos="0 0 1"><freejoint/>'
                    '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.2 0.3"/>'
                    '<body name="c" pos="0.1 0 0"><joint axis="0 1 0"/>'
                    '<inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.02 0.02"/></body></body>'
                    "</worldbody></mujoco>")
    robot = load_robot(path, analytic="parser")
    assert list(robot.joints) == ["joint0", "joint1"] == list(robot.pin_model.names)[1:]
    paired = "unnamed MuJoCo joints paired through the bodies they move: cJoint_0 -> joint1 ('c')"
    assert paired in robot.source.edits
    _clean(crosscheck(robot, n_states=20))


def test_a_joint_map_file_that_is_not_text_is_named_not_a_traceback(tmp_path):
    path = tmp_path / "map.bin"
    path.write_bytes(b"\xff\xfea=b")
    with pytest.raises(JointMapError, match=r"file '.*map.bin' cannot be read \(.*codec.*PIN_JOINT="):
        parse_joint_map(str(path))
