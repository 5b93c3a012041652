"""Load-time model edits that derive a new Robot from an existing one (MjSpec + Pinocchio)."""

from __future__ import annotations

from collections.abc import Callable, Iterable

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.exceptions import RobotError
from mbctl.robots.model_pair import Robot

#: Radius [m] of the small solid sphere a payload is (its rotational inertia 2/5 m r^2 about its
#: centre): close to a point mass, and MuJoCo writes an inertial only with some inertia.
PAYLOAD_RADIUS_M = 0.01

#: Largest payload mass, as a multiple of the robot's own mass [-]. A payload is something the
#: robot carries: at 1000 times its mass its actuators cannot hold it, and the payload's share of
#: M(q) swamps the links the options exist to study (1e30 kg made a plant that still "ran").
MAX_PAYLOAD_MASS_RATIO = 1000.0

#: Largest distance [m] of a payload from the body it is fixed to: beyond the reach of any robot
#: in the catalogue (the G1 is 1.3 m tall). At 1e9 m both engines' forward kinematics lose the
#: 1e-9 m the load-time agreement check holds them to (double precision: 1e9 x 2.2e-16 = 2e-7 m).
MAX_PAYLOAD_OFFSET_M = 10.0


def position_to_motor(robot: Robot, actuators: Iterable[str] | None = None) -> Robot:
    """Turn position (or velocity) actuators into torque motors, so torque controllers can run.

    Each converted actuator becomes a motor with gear 1 whose ctrlrange is the actuator's force
    range (from ``forcerange`` or the joint's ``actuatorfrcrange``); ctrl then means [N m].

    Args:
        robot: The robot to convert (unchanged).
        actuators: Names to convert; default: every position and velocity actuator.

    Returns:
        A new Robot whose ``source.edits`` records the conversion.
    """
    names = list(actuators) if actuators is not None else [
        a.name for a in robot.actuators.values() if a.kind in ("position", "velocity")
    ]
    infos = [robot.actuator(n) for n in names]

    def edit(spec: mujoco.MjSpec) -> None:
        for info in infos:
            act = spec.actuators[info.index]  # by index: an unnamed actuator has no name in the spec
            act.set_to_motor()
            act.gear = np.array([info.gear, 0, 0, 0, 0, 0])
            lo, hi = info.force_range
            if np.isfinite(lo) and np.isfinite(hi):
                act.ctrlrange = np.array([lo, hi])
                act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            else:
                act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            act.inheritrange = 0
        # keyframe ctrl values were position targets; as torques they would be meaningless
        for key in spec.keys:
            key.ctrl = np.zeros(0)

    return robot.with_edits(f"position actuators -> torque motors: {len(infos)} actuators", mj_edit=edit)


def weld_base(robot: Robot, keyframe: str | None = None) -> Robot:
    """Weld a floating base to the world at a keyframe's pose, in both engines.

    MuJoCo: the free joint is deleted from the MjSpec, the base body is placed at the keyframe's
    base position and orientation, every keyframe drops the free joint's 7 qpos and 6 qvel
    entries, and contacts between the base and its child bodies are excluded (MuJoCo does not
    filter parent-child contacts of a body welded to the world, so they would start to collide).
    Pinocchio: the model is rebuilt from the edited spec
    (:func:`~mbctl.robots.model_files.pin_model_from_spec`), so it has no free-flyer and the same
    fixed base pose. The pair is then checked for agreement like any loaded robot.

    Args:
        robot: A robot whose first joint is a free joint (unchanged).
        keyframe: Keyframe giving the base pose (default: the first keyframe; the body's
            model pose when there is none).

    Returns:
        A fixed-base Robot; ``source.edits`` records the weld and the pose.

    Raises:
        ModelMismatchError: The rebuilt Pinocchio model disagrees with the welded MuJoCo model.
        UnknownNameError: Unknown keyframe.
        RobotError: The robot has no floating base.
    """
    from mbctl.robots.exceptions import RobotError
    from mbctl.robots.model_files import pin_model_from_spec

    if not robot.has_floating_base:
        raise RobotError(
            f"{robot.name!r} has no floating base to weld (first joint: "
            f"{next(iter(robot.joints), 'none')!r}); weld_base needs a free joint"
        )
    free = next(iter(robot.joints.values()))
    m = robot.mj_model
    if keyframe is None and robot.keyframes:
        keyframe = robot.keyframes[0]
    pos: np.ndarray | None = None
    quat_wxyz: np.ndarray | None = None
    if keyframe is not None:
        qpos = np.array(m.key_qpos[robot.keyframe_id(keyframe)])
        pos, quat_wxyz = qpos[free.qposadr : free.qposadr + 3], qpos[free.qposadr + 3 : free.qposadr + 7]
    edited: list[mujoco.MjSpec] = []

    def edit(spec: mujoco.MjSpec) -> None:
        joint = spec.joint(free.name)
        body = joint.parent
        spec.delete(joint)
        # MuJoCo filters parent-child contacts except for bodies welded to the world; keep the
        # floating robot's behaviour by excluding the base from its children explicitly.
        for child in body.bodies:
            spec.add_exclude(bodyname1=body.name, bodyname2=child.name)
        if pos is not None and quat_wxyz is not None:
            body.pos = np.array(pos)
            body.quat = np.array(quat_wxyz)
        keep_q = np.r_[0 : free.qposadr, free.qposadr + free.nq : m.nq]
        keep_v = np.r_[0 : free.dofadr, free.dofadr + free.nv : m.nv]
        for key in spec.keys:
            if len(key.qpos) == m.nq:
                key.qpos = np.asarray(key.qpos)[keep_q]
            if len(key.qvel) == m.nv:
                key.qvel = np.asarray(key.qvel)[keep_v]
        edited.append(spec)

    def pin_edit(_model):  # noqa: ANN001, ANN202 - pin.Model in, pin.Model out
        return pin_model_from_spec(edited[-1])

    where = "at its model pose"
    if pos is not None and quat_wxyz is not None:
        where = (f"at keyframe {keyframe!r} pose p={np.round(pos, 6).tolist()} m, "
                 f"quat_wxyz={np.round(quat_wxyz, 6).tolist()}")
    return robot.with_edits(f"base welded to the world ({free.name} removed) {where}",
                            mj_edit=edit, pin_edit=pin_edit)


def add_site(robot: Robot, site: str, body: str, position_in_body_m: Iterable[float] = (0.0, 0.0, 0.0),
             size_m: float = 0.01) -> Robot:
    """Add a site to a body in both engines (identity orientation in the body frame).

    MuJoCo: ``MjSpec`` ``add_site`` on ``body`` at ``position_in_body_m``. Pinocchio: an
    ``OP_FRAME`` called ``site`` on the body's parent joint, placed at (body frame placement) *
    (offset), so both engines put it at the same point.

    Args:
        robot: The robot to extend (unchanged).
        site: New site name (must not exist yet in either engine).
        body: Name of the body that carries the site.
        position_in_body_m: Site position (3,) [m] in the body frame.
        size_m: Site size [m] (visual only).

    Returns:
        A new Robot whose ``source.edits`` records the site.

    Raises:
        UnknownNameError: ``body`` is not a body of the robot (the message lists close names).
        RobotError: ``site`` already names a site or a Pinocchio frame, or the offset is not 3
            finite numbers.
    """
    import pinocchio as pin

    from mbctl.robots.exceptions import RobotError

    robot.body_id(body)  # UnknownNameError with close matches
    if site in robot.sites or robot.pin_model.existFrame(site):
        raise RobotError(f"{robot.name!r} already has a site or frame called {site!r}; choose another name")
    offset = np.asarray(list(position_in_body_m), dtype=float)
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise RobotError(f"position_in_body_m must be 3 finite numbers [m]; got {position_in_body_m!r}")

    def mj_edit(spec: mujoco.MjSpec) -> None:
        spec.body(body).add_site(name=site, pos=offset, size=[size_m, size_m, size_m])

    def pin_edit(model: pin.Model) -> pin.Model:
        body_frame_id = model.getFrameId(body, pin.FrameType.BODY)
        body_frame = model.frames[body_frame_id]
        placement = body_frame.placement * pin.SE3(np.eye(3), offset)
        model.addFrame(pin.Frame(site, body_frame.parentJoint, body_frame_id, placement,
                                 pin.FrameType.OP_FRAME))
        return model

    return robot.with_edits(
        f"site {site} on body {body} at {np.round(offset, 6).tolist()} m in the body frame "
        "(MjSpec add_site; Pinocchio OP_FRAME)",
        mj_edit,
        pin_edit,
    )


def scale_masses(model: pin.Model, factor: float) -> pin.Model:
    """A copy of the Pinocchio ``model`` with every body's mass and rotational inertia times ``factor``.

    Centres of mass and rotor armature are unchanged (armature is a motor property). The jobs'
    ``--model-error PCT`` gives a controller this model (``factor = 1 + PCT / 100``) while the
    plant keeps the true one.
    """
    out = model.copy()
    for i in range(1, len(out.inertias)):
        inertia = out.inertias[i]
        out.inertias[i] = pin.Inertia(inertia.mass * factor, inertia.lever, inertia.inertia * factor)
    return out


def set_inertial(body: mujoco.MjsBody, mass_kg: float, com_m: Iterable[float],
                 inertia_com: np.ndarray) -> None:
    """Write an explicit ``<inertial>`` into an MjSpec body: mass, CoM and the 3x3 inertia.

    The inertia (about the CoM, in the body frame) is stored as MuJoCo does after compiling: its
    principal moments (``inertia``) and principal axes (``iquat``, a right-handed frame).

    Args:
        body: The MjSpec body (edited in place).
        mass_kg: Mass [kg] (> 0).
        com_m: Centre of mass (3,) [m] in the body frame.
        inertia_com: Rotational inertia (3, 3) [kg m^2] about the CoM, body axes (symmetric).
    """
    moments, axes = np.linalg.eigh(0.5 * (inertia_com + inertia_com.T))
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    quat_wxyz = np.zeros(4)
    mujoco.mju_mat2Quat(quat_wxyz, axes.ravel())
    body.explicitinertial = True
    body.mass = float(mass_kg)
    body.ipos = np.asarray(list(com_m), dtype=float)  # set even when zero: MuJoCo writes it then
    body.iquat = quat_wxyz
    body.inertia = moments
    body.fullinertia = np.array([np.nan, 0, 0, 0, 0, 0])


def body_inertial(m: mujoco.MjModel, b: int) -> tuple[float, np.ndarray, np.ndarray]:
    """Compiled body ``b``'s mass [kg], CoM (3,) [m] and inertia about the CoM (3, 3), body frame."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, m.body_iquat[b])
    R_BI = R.reshape(3, 3)
    return float(m.body_mass[b]), np.array(m.body_ipos[b]), R_BI @ np.diag(m.body_inertia[b]) @ R_BI.T


def scale_link_masses(robot: Robot, factor: float) -> Robot:
    """The plant's link masses and rotational inertias times ``factor`` (CoMs unchanged).

    What ``--plant-error PCT`` does to the plant (``factor = 1 + PCT/100``), as
    :func:`scale_masses` (``--model-error``) does to a controller's model. Every body of the
    robot gets an explicit inertial with the compiled values scaled, so inertias MuJoCo derived
    from geoms scale too; scene bodies are unchanged.

    Raises:
        RobotError: ``factor`` is not finite and > 0.
    """
    if not (np.isfinite(factor) and factor > 0):
        raise RobotError(f"mass factor must be finite and > 0; got {factor}")
    m = robot.mj_model
    names = dict(zip(robot.robot_body_ids, robot.bodies, strict=True))

    def edit(spec: mujoco.MjSpec) -> None:
        for b, name in names.items():
            mass, com, inertia = body_inertial(m, b)
            if mass > 0:
                set_inertial(spec.body(name), mass * factor, com, inertia * factor)

    return robot.with_edits(f"plant link masses and inertias x {factor:g}", mj_edit=edit)


def check_payload_offset(offset_m: Iterable[float]) -> None:
    """RobotError if a payload offset (3,) [m] is farther than :data:`MAX_PAYLOAD_OFFSET_M` from its body."""
    distance = float(np.linalg.norm(np.asarray(list(offset_m), dtype=float)))
    if not distance <= MAX_PAYLOAD_OFFSET_M:
        raise RobotError(f"payload offset {list(offset_m)} m is {distance:g} m from its body; a payload "
                         f"sits on the robot, at most {MAX_PAYLOAD_OFFSET_M:g} m away")


def add_payload(robot: Robot, mass_kg: float, body: str, offset_m: Iterable[float] = (0.0, 0.0, 0.0)
                ) -> Robot:
    """Fix a payload (a small solid sphere, nearly a point mass) to ``body``, in both engines.

    MuJoCo: a child body ``payload_<body>`` at ``offset_m`` in ``body``'s frame with mass
    ``mass_kg`` and the inertia of a solid sphere of radius :data:`PAYLOAD_RADIUS_M`, and a red
    visual sphere (no collisions). Pinocchio (rebuilt from the plant) adds it to the body's joint.

    Args:
        robot: The robot (unchanged).
        mass_kg: Payload mass [kg] (> 0).
        body: A body of the robot.
        offset_m: Payload centre (3,) [m] in the body frame.

    Raises:
        UnknownNameError: ``body`` is not a body of the robot.
        RobotError: A mass that is not > 0 or above :data:`MAX_PAYLOAD_MASS_RATIO` times the
            robot's mass, or an offset that is not 3 finite numbers within
            :data:`MAX_PAYLOAD_OFFSET_M` of the body.
    """
    if body not in robot.bodies:
        from mbctl.robots.exceptions import UnknownNameError

        raise UnknownNameError("robot body", body, robot.bodies)
    offset = np.asarray(list(offset_m), dtype=float)
    if not (np.isfinite(mass_kg) and mass_kg > 0):
        raise RobotError(f"payload mass must be finite and > 0 kg; got {mass_kg}")
    robot_mass = float(np.sum(robot.mj_model.body_mass[list(robot.robot_body_ids)]))
    if mass_kg > MAX_PAYLOAD_MASS_RATIO * robot_mass:
        raise RobotError(f"payload mass {mass_kg:g} kg is more than {MAX_PAYLOAD_MASS_RATIO:g} times the "
                         f"robot's own mass ({robot_mass:.4g} kg): at most "
                         f"{MAX_PAYLOAD_MASS_RATIO * robot_mass:.4g} kg for {robot.name!r}")
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise RobotError(f"payload offset must be 3 finite numbers [m]; got {offset_m!r}")
    check_payload_offset(offset)
    name = f"payload_{body}"
    inertia = 0.4 * mass_kg * PAYLOAD_RADIUS_M**2

    def edit(spec: mujoco.MjSpec) -> None:
        child = spec.body(body).add_body(name=name, pos=offset)
        set_inertial(child, mass_kg, np.zeros(3), np.eye(3) * inertia)
        child.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[max(PAYLOAD_RADIUS_M, 0.02), 0, 0],
                       contype=0, conaffinity=0, group=1, rgba=[0.9, 0.2, 0.2, 1.0])

    return robot.with_edits(f"payload {mass_kg:g} kg on {body} at {np.round(offset, 6).tolist()} m "
                            f"(body frame), body {name}", mj_edit=edit)


#: What a contact sensor of :func:`add_contact_sensors` reports (MuJoCo's ``mjtConDataField`` bits):
#: the number of contacts, the net force [N] and the net moment [N m] about the contacts'
#: force-weighted centroid, and that centroid [m], world axes (10 values).
CONTACT_SENSOR_DATA = ("found", "force", "torque", "pos")
#: MuJoCo's contact-sensor reduction that merges a body's contacts into one net contact.
NETFORCE = 3


def contact_data_bit(field: str) -> int:
    """MuJoCo's bit of a contact sensor's data field (``"found"``, ``"force"``, ...: ``mjtConDataField``)."""
    return int(getattr(mujoco.mjtConDataField, f"mjCONDATA_{field.upper()}"))


def contact_sensor_name(body: str) -> str:
    """The name :func:`add_contact_sensors` gives the contact sensor of ``body``."""
    return f"{body}_contact"


def add_contact_sensors(robot: Robot, bodies: Iterable[str]) -> Robot:
    """Add one MuJoCo contact sensor per body: the net contact force and moment on it, every step.

    Each sensor (``<contact body1=BODY reduce="netforce" data="found force torque pos"/>``) makes
    MuJoCo itself sum the body's contacts during the step's forward pass (in C), so a monitor that
    reads the force on a foot every control period (:class:`mbctl.sim.contacts.ContactSensor`) reads
    10 numbers instead of looping over the contacts in Python. The physics is unchanged; Pinocchio's
    model too (sensors are MuJoCo's only).

    Args:
        robot: The robot to extend (unchanged).
        bodies: Robot bodies (e.g. the feet); idempotent for a body that has the sensor already.

    Returns:
        A new Robot whose ``source.edits`` records the sensors (the same robot if none is new).

    Raises:
        UnknownNameError: A body that is not the robot's.
        RobotError: A sensor of another kind holds the name :func:`contact_sensor_name` gives.
    """
    new = _without_contact_sensor(robot, bodies, contact_sensor_name)
    if not new:
        return robot
    fields = sum(1 << contact_data_bit(f) for f in CONTACT_SENSOR_DATA)

    def mj_edit(spec: mujoco.MjSpec) -> None:
        for body in new:
            sensor = spec.add_sensor()
            sensor.name = contact_sensor_name(body)
            sensor.type = mujoco.mjtSensor.mjSENS_CONTACT
            sensor.objtype = mujoco.mjtObj.mjOBJ_BODY
            sensor.objname = body
            sensor.intprm[0] = fields  # the data fields, as bits
            sensor.intprm[1] = NETFORCE  # one net contact
            sensor.intprm[2] = 1  # one slot

    return robot.with_edits(f"contact sensors (net force) on {', '.join(new)} (MjSpec add_sensor)", mj_edit)


def floor_sensor_name(body: str | None) -> str:
    """The name :func:`add_floor_sensors` gives the floor contacts' count of ``body`` (None: the robot's)."""
    return "robot_floor_contacts" if body is None else f"{body}_floor_contacts"


def add_floor_sensors(robot: Robot, bodies: Iterable[str]) -> Robot:
    """Count the robot's contacts with the floor every step: all of them, and each of ``bodies``'.

    The floor is the world body's geoms. One MuJoCo contact sensor (``<contact subtree1=ROOT
    body2="world" data="found"/>``) counts the contacts between the robot and the floor, and one per
    body (``body1=BODY body2="world"``) that body's. Where the bodies' counts add up to the
    robot's, no other body of the robot touches the floor: a plant monitor
    (:class:`mbctl.sim.monitor.PlantMonitor`, whose fall rule checks the bodies on the floor every
    control period) then names them from these numbers, read with the feet's contact sensors,
    instead of reading every contact's geom pair. The physics is unchanged; Pinocchio's model too.

    Args:
        robot: A robot that is one tree (a floating base with its limbs; unchanged).
        bodies: Robot bodies that stand on the floor (e.g. the feet); idempotent.

    Returns:
        A new Robot whose ``source.edits`` records the sensors (the same robot if none is new).

    Raises:
        UnknownNameError: A body that is not the robot's.
        RobotError: A robot of several trees, or a sensor of another kind under the names
            :func:`floor_sensor_name` gives.
    """
    if robot.tree_root_id is None:
        raise RobotError(f"floor sensors count the contacts of one tree of bodies; {robot.name!r} has more")
    root = mujoco.mj_id2name(robot.mj_model, mujoco.mjtObj.mjOBJ_BODY, robot.tree_root_id)
    new = _without_contact_sensor(robot, [root, *bodies],
                                  lambda b: floor_sensor_name(None if b == root else b))
    if not new:
        return robot
    found = 1 << contact_data_bit("found")

    def mj_edit(spec: mujoco.MjSpec) -> None:
        for body in new:
            sensor = spec.add_sensor()
            sensor.name = floor_sensor_name(None if body == root else body)
            sensor.type = mujoco.mjtSensor.mjSENS_CONTACT
            # the root's whole subtree (MuJoCo's "subtree1"), or the body alone
            sensor.objtype = mujoco.mjtObj.mjOBJ_XBODY if body == root else mujoco.mjtObj.mjOBJ_BODY
            sensor.objname = body
            sensor.reftype = mujoco.mjtObj.mjOBJ_BODY
            sensor.refname = "world"
            sensor.intprm[0] = found  # the number of matching contacts alone
            sensor.intprm[2] = 1  # one slot

    named = ", ".join("the robot" if b == root else b for b in new)
    return robot.with_edits(f"floor contact counts on {named} (MjSpec add_sensor)", mj_edit)


def _without_contact_sensor(robot: Robot, bodies: Iterable[str], name_of: Callable[[str], str]) -> list[str]:
    """The bodies that have no contact sensor named ``name_of(body)`` yet (checked: robot bodies).

    Raises:
        UnknownNameError: A body that is not the robot's.
        RobotError: A sensor of another kind holds one of those names.
    """
    m = robot.mj_model
    new = []
    for body in bodies:
        robot.body_id(body)  # UnknownNameError with close matches
        name = name_of(body)
        sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, name)
        if sid >= 0:
            if int(m.sensor_type[sid]) != int(mujoco.mjtSensor.mjSENS_CONTACT):
                raise RobotError(f"{robot.name!r} has a sensor called {name!r} that is not a contact sensor")
            continue
        new.append(body)
    return new


def standalone_xml(robot: Robot, spec: mujoco.MjSpec | None = None) -> str:
    """The MJCF of ``robot`` (or of ``spec``, an edited copy of its spec), loadable from any folder.

    Mesh and texture folders are made absolute (relative to the scene file), so the XML can be
    written anywhere (a run folder's ``model.xml``, an ``identified.xml``).
    """
    spec = (spec or robot.mj_spec).copy()
    base = robot.source.scene_file.parent
    spec.meshdir = str((base / spec.meshdir).resolve()) if spec.meshdir else str(base)
    spec.texturedir = str((base / spec.texturedir).resolve()) if spec.texturedir else str(base)
    return spec.to_xml()
