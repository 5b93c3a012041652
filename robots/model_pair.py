"""The model pair: one robot as a Pinocchio model (the analytic model) and a MuJoCo model (the plant).

Both come from the same MJCF: Pinocchio reads the robot file, MuJoCo the scene file (which may
``<include>`` the robot file, something Pinocchio's parser cannot follow). On construction the
pair is checked for agreement (``robots/agreement.py``: joint names and order, nq, nv, total mass,
armature, forward kinematics). Where the models come from and how their files are read is in
``robots/model_files.py``; ``ModelSource``, the loaders and ``check_agreement`` are re-exported here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import TypeVar

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.robots.agreement import check_agreement
from mbctl.robots.conventions import JointLayout, StateConverter
from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.indexing import as_slice
from mbctl.robots.model_files import (
    ModelSource,
    compile_spec,
    load_mj_spec,
    load_pin_model,
    pin_model_from_spec,
)
from mbctl.robots.names import ActuatorInfo, SensorInfo, actuator_infos, mj_name, names_of, sensor_infos
from mbctl.robots.pin_from_mj import pin_model_from_mj
from mbctl.robots.scene import describe_body, robot_bodies, scene_bodies

__all__ = ["JACOBIAN_REFERENCES", "ModelSource", "Robot", "check_agreement", "compile_spec", "load_mj_spec",
           "load_pin_model", "pin_model_from_spec"]

_T = TypeVar("_T")

_MJ_JOINT_KIND = {
    mujoco.mjtJoint.mjJNT_FREE: "free",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
    mujoco.mjtJoint.mjJNT_HINGE: "hinge",
    mujoco.mjtJoint.mjJNT_SLIDE: "slide",
}

#: Jacobian reference frames by name (see ``Robot.jacobian``).
JACOBIAN_REFERENCES: Mapping[str, pin.ReferenceFrame] = MappingProxyType(
    {
        "world_aligned": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
        "local": pin.ReferenceFrame.LOCAL,
        "world": pin.ReferenceFrame.WORLD,
    }
)

class Robot:
    """A robot's Pinocchio model and MuJoCo model, with name maps and convention conversions.

    The public state convention is Pinocchio's: free-flyer quaternions (x, y, z, w) and base
    velocity in the base frame. ``converter`` maps to and from MuJoCo's convention.

    Attributes:
        source: Where the models come from and which load-time edits were made.
        pin_model: Pinocchio model (gravity copied from the MuJoCo model's ``opt.gravity``).
        mj_model: MuJoCo model of the plant (scene).
        mj_spec: The MjSpec ``mj_model`` was compiled from (for further load-time edits).
        converter: Conversions between the two conventions.
        joints: Joint layouts by name, in model order (q and v slices are the same in both).
        actuators: Actuators by name, in ctrl order.
        sensors: Sensors by name, in sensordata order.
        sites: Site names (MuJoCo ids; Pinocchio frames of the same name).
        bodies: Body names, world excluded.
        keyframes: Keyframe names.
    """

    def __init__(
        self,
        source: ModelSource,
        pin_model: pin.Model | None,
        mj_spec: mujoco.MjSpec,
        check: bool = True,
        mj_model: mujoco.MjModel | None = None,
    ):
        """Build the pair.

        ``pin_model=None`` builds the analytic model from the compiled MjModel. ``check=False``
        skips the agreement check (for cross-checking a deliberately different Pinocchio model
        against the plant). ``mj_model``: ``mj_spec`` already compiled by the caller.
        """
        self.source = source
        self.mj_spec = mj_spec
        self.mj_model = compile_spec(mj_spec, source.scene_file) if mj_model is None else mj_model
        m = self.mj_model
        # The robot is a set of whole trees; the rest of the plant is scene (robots/scene.py).
        in_robot = robot_bodies(m, source.roots)
        #: MuJoCo ids of the robot's bodies and sites, in id order (parallel to bodies, sites).
        self.robot_body_ids: tuple[int, ...] = tuple(sorted(in_robot))
        self.robot_site_ids = tuple(s for s in range(m.nsite) if int(m.site_bodyid[s]) in in_robot)
        roots = [b for b in self.robot_body_ids if int(m.body_parentid[b]) == 0]
        #: MuJoCo id of the robot's one root body when the robot is one tree (that body's whole
        #: subtree, e.g. a floating base with its limbs), else None.
        self.tree_root_id: int | None = roots[0] if len(roots) == 1 else None
        # None: the analytic model is built from the compiled plant (see robots/pin_from_mj.py)
        self.pin_model = pin_model_from_mj(m, in_robot) if pin_model is None else pin_model
        self.pin_model.gravity = pin.Motion(np.array(m.opt.gravity), np.zeros(3))
        layouts: list[JointLayout] = []
        iq, iv = 0, 0
        for j in range(m.njnt):
            if int(m.jnt_bodyid[j]) not in in_robot:
                continue
            kind = _MJ_JOINT_KIND[mujoco.mjtJoint(int(m.jnt_type[j]))]
            nq = {"free": 7, "ball": 4}.get(kind, 1)
            nv = {"free": 6, "ball": 3}.get(kind, 1)
            name = mj_name(m, mujoco.mjtObj.mjOBJ_JOINT, j)  # as pin_from_mj
            plant_q, plant_v = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
            layouts.append(JointLayout(name, kind, iq, iv, nq, nv, plant_q, plant_v))
            iq, iv = iq + nq, iv + nv
        self.joints: Mapping[str, JointLayout] = MappingProxyType({j.name: j for j in layouts})
        self.converter = StateConverter(layouts, iq, iv)
        #: The robot's coordinates in the plant's qpos and qvel: a slice when they are contiguous
        #: (every robot without interleaved scene joints), else an index array.
        self.qpos_index = as_slice([k for j in layouts for k in range(j.qposadr, j.qposadr + j.nq)])
        self.qvel_index = as_slice([k for j in layouts for k in range(j.dofadr, j.dofadr + j.nv)])
        self.actuators: Mapping[str, ActuatorInfo] = MappingProxyType(actuator_infos(m))
        self.sensors: Mapping[str, SensorInfo] = MappingProxyType(sensor_infos(m))
        all_bodies = names_of(m, mujoco.mjtObj.mjOBJ_BODY, m.nbody)
        all_sites = names_of(m, mujoco.mjtObj.mjOBJ_SITE, m.nsite)
        self._body_ids = {n: b for b, n in enumerate(all_bodies) if b > 0 and n}
        self._site_ids = {n: s for s, n in enumerate(all_sites) if n}
        self.bodies = tuple(all_bodies[b] for b in self.robot_body_ids)
        self.sites = tuple(all_sites[s] for s in self.robot_site_ids)
        self.scene_body_ids: tuple[int, ...] = tuple(scene_bodies(m, in_robot))
        self.keyframes = names_of(m, mujoco.mjtObj.mjOBJ_KEY, m.nkey)
        self._pin_data: pin.Data | None = None  # created on first use by the dynamics helpers
        if check:
            check_agreement(self)

    # ------------------------------------------------------------------ basic facts
    @property
    def name(self) -> str:
        """Robot name."""
        return self.source.name

    @property
    def nq(self) -> int:
        """Configuration dimension."""
        return self.pin_model.nq

    @property
    def nv(self) -> int:
        """Velocity (tangent) dimension."""
        return self.pin_model.nv

    @property
    def nu(self) -> int:
        """Number of actuators."""
        return self.mj_model.nu

    @property
    def has_floating_base(self) -> bool:
        """Whether the first joint is a free joint."""
        return bool(self.joints) and next(iter(self.joints.values())).kind == "free"

    @property
    def timestep_s(self) -> float:
        """MuJoCo physics timestep [s]."""
        return float(self.mj_model.opt.timestep)

    @property
    def covers_plant(self) -> bool:
        """Whether the robot's q and v are the plant's whole qpos and qvel (no scene coordinates)."""
        return (self.nq, self.nv) == (self.mj_model.nq, self.mj_model.nv)

    def plant_qpos(self, q: npt.ArrayLike, qpos: np.ndarray | None = None) -> np.ndarray:
        """The plant's qpos with the robot at ``q`` (Pinocchio convention).

        Args:
            q: Robot configuration (nq,).
            qpos: The plant's qpos to write into (its scene coordinates are kept); default: a
                copy of the model's ``qpos0``.
        """
        out = np.array(self.mj_model.qpos0) if qpos is None else qpos
        out[self.qpos_index] = self.converter.q_pin_to_mj(q)
        return out

    def robot_q(self, qpos: npt.ArrayLike) -> np.ndarray:
        """The robot's configuration (nq,), Pinocchio convention, read from a plant qpos."""
        return self.converter.q_mj_to_pin(np.asarray(qpos, dtype=float)[self.qpos_index])

    # ------------------------------------------------------------------ lookups
    def joint(self, name: str) -> JointLayout:
        """The joint called ``name``; UnknownNameError lists close matches."""
        return _lookup("joint", self.joints, name)

    def actuator(self, name: str) -> ActuatorInfo:
        """The actuator called ``name``; UnknownNameError lists close matches."""
        return _lookup("actuator", self.actuators, name)

    def actuator_for_joint(self, joint: str) -> ActuatorInfo:
        """The (first) actuator driving ``joint``."""
        self.joint(joint)
        for info in self.actuators.values():
            if info.joint == joint:
                return info
        raise UnknownNameError(
            "actuated joint", joint, [a.joint for a in self.actuators.values() if a.joint]
        )

    def sensor(self, name: str) -> SensorInfo:
        """The sensor called ``name``; UnknownNameError lists close matches."""
        return _lookup("sensor", self.sensors, name)

    def site_id(self, name: str) -> int:
        """MuJoCo id of site ``name`` (a site of the robot or of the scene)."""
        return _lookup("site", self._site_ids, name)

    def body_id(self, name: str) -> int:
        """MuJoCo id of body ``name`` (of the robot or of the scene; the world is 0)."""
        return _lookup("body", self._body_ids, name)

    @property
    def scene_bodies(self) -> tuple[str, ...]:
        """The plant's bodies that are not the robot (static, mocap, free objects), described."""
        return tuple(describe_body(self.mj_model, b) for b in self.scene_body_ids)

    def frame_id(self, name: str) -> int:
        """Pinocchio frame id of a site or body called ``name``."""
        if not self.pin_model.existFrame(name):
            known = [f.name for f in self.pin_model.frames]
            raise UnknownNameError("frame", name, known)
        return self.pin_model.getFrameId(name)

    def keyframe_id(self, name: str) -> int:
        """MuJoCo keyframe id of ``name``."""
        if name not in self.keyframes:
            raise UnknownNameError("keyframe", name, self.keyframes)
        return self.keyframes.index(name)

    def keyframe_q(self, name: str) -> np.ndarray:
        """Configuration (nq,) of keyframe ``name``, Pinocchio convention."""
        return self.robot_q(self.mj_model.key_qpos[self.keyframe_id(name)])

    def keyframe_ctrl(self, name: str) -> np.ndarray:
        """Actuator controls (nu,) stored in keyframe ``name``."""
        return np.array(self.mj_model.key_ctrl[self.keyframe_id(name)])

    def neutral_q(self) -> np.ndarray:
        """Neutral configuration (nq,) (identity quaternions, zero angles), Pinocchio convention."""
        return pin.neutral(self.pin_model)

    # ------------------------------------------------------------------ analytic model (Pinocchio)
    @property
    def _data(self) -> pin.Data:
        """Scratch Pinocchio data of the helpers below, created on first use (they return copies)."""
        if self._pin_data is None:
            self._pin_data = self.pin_model.createData()
        return self._pin_data

    def _q(self, q: npt.ArrayLike) -> np.ndarray:
        return self.converter.check_q(q, "q")

    def mass_matrix(self, q: npt.ArrayLike) -> np.ndarray:
        """Joint-space mass matrix ``M(q)`` (Pinocchio's CRBA, symmetrized).

        Args:
            q: Configuration (nq,), Pinocchio convention (free-flyer ``p_WB`` [m], then
                ``quat_xyzw``; joint angles [rad] or positions [m]).

        Returns:
            ``M`` (nv, nv), a new symmetric array [kg m^2] (rotational), [kg] (translational),
            in Pinocchio's velocity convention (free-flyer velocity in the base frame B).

        Raises:
            StateError: ``q`` has the wrong shape or non-finite entries.
        """
        M = pin.crba(self.pin_model, self._data, self._q(q))
        return np.triu(M) + np.triu(M, 1).T

    def gravity(self, q: npt.ArrayLike) -> np.ndarray:
        """Generalized gravity ``g(q)``: the force that holds the robot still (``tau = g``).

        Args:
            q: Configuration (nq,), Pinocchio convention.

        Returns:
            ``g`` (nv,) [N m] on rotational, [N] on translational coordinates (a new array),
            free-flyer rows in the base frame B; gravity is MuJoCo's ``opt.gravity``.

        Raises:
            StateError: ``q`` has the wrong shape or non-finite entries.
        """
        return np.array(pin.computeGeneralizedGravity(self.pin_model, self._data, self._q(q)))

    def bias(self, q: npt.ArrayLike, v: npt.ArrayLike) -> np.ndarray:
        """Bias forces ``b(q, v) = C(q, v) v + g(q)`` (Coriolis, centrifugal and gravity).

        ``M(q) a + b(q, v) = tau`` is the equation of motion (``pin.nonLinearEffects``).

        Args:
            q: Configuration (nq,), Pinocchio convention.
            v: Velocity (nv,), Pinocchio convention (free-flyer ``v_WB_B`` [m/s] and
                ``w_WB_B`` [rad/s] in the base frame B; joint rates [rad/s] or [m/s]).

        Returns:
            ``b`` (nv,) [N m] or [N] (a new array), free-flyer rows in the base frame B.

        Raises:
            StateError: ``q`` or ``v`` has the wrong shape or non-finite entries.
        """
        q_ = self._q(q)
        v_ = self.converter.check_v(v, "v")
        return np.array(pin.nonLinearEffects(self.pin_model, self._data, q_, v_))

    def jacobian(self, frame: str, q: npt.ArrayLike, reference: str = "world_aligned") -> np.ndarray:
        """Geometric Jacobian ``J`` of a site, body or frame: ``[v_F; w_F] = J(q) v``.

        Args:
            frame: Site, body or Pinocchio frame name (see ``frame_id``).
            q: Configuration (nq,), Pinocchio convention.
            reference: Frame the twist is expressed in: ``"world_aligned"`` (velocity of the
                frame origin, in world axes: Pinocchio's LOCAL_WORLD_ALIGNED), ``"local"``
                (in the frame's own axes F) or ``"world"`` (spatial velocity at the world
                origin, in world axes).

        Returns:
            ``J`` (6, nv), a new array: rows 0-2 linear velocity [m/s per unit of v], rows 3-5
            angular velocity [rad/s per unit of v], columns in Pinocchio's velocity convention.

        Raises:
            UnknownNameError: An unknown ``frame`` or ``reference`` (lists close matches).
            StateError: ``q`` has the wrong shape or non-finite entries.
        """
        if reference not in JACOBIAN_REFERENCES:
            raise UnknownNameError("Jacobian reference", reference, JACOBIAN_REFERENCES)
        frame_id = self.frame_id(frame)
        q_ = self._q(q)
        return np.array(
            pin.computeFrameJacobian(
                self.pin_model, self._data, q_, frame_id, JACOBIAN_REFERENCES[reference]
            )
        ).reshape(6, -1)  # the bindings return a (6,) vector when nv = 1

    def frame_pose(self, frame: str, q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Pose of a site, body or frame F in the world frame W (Pinocchio's kinematics).

        Args:
            frame: Site, body or Pinocchio frame name (see ``frame_id``).
            q: Configuration (nq,), Pinocchio convention.

        Returns:
            ``p_WF`` (3,) [m], the frame origin in W, and ``R_WF`` (3, 3), which rotates
            F-frame vectors into W (new arrays).

        Raises:
            UnknownNameError: An unknown ``frame`` (lists close matches).
            StateError: ``q`` has the wrong shape or non-finite entries.
        """
        frame_id = self.frame_id(frame)
        q_ = self._q(q)
        data = self._data
        pin.forwardKinematics(self.pin_model, data, q_)
        X_WF = pin.updateFramePlacement(self.pin_model, data, frame_id)
        return np.array(X_WF.translation), np.array(X_WF.rotation)

    # ------------------------------------------------------------------ derived models
    def with_edits(
        self,
        description: str,
        mj_edit: Callable[[mujoco.MjSpec], None] | None = None,
        pin_edit: Callable[[pin.Model], pin.Model] | None = None,
    ) -> Robot:
        """A new Robot with load-time edits applied to copies of the models.

        Args:
            description: What the edit does, recorded in ``source.edits`` and in reports.
            mj_edit: Mutates a copy of the MjSpec (e.g. add sites, convert actuators).
            pin_edit: Returns an edited Pinocchio model from a copy of ``pin_model``.
        """
        spec = self.mj_spec.copy()
        if mj_edit is not None:
            mj_edit(spec)
        pin_model: pin.Model | None = None  # built again from the edited plant
        if self.source.analytic != "mujoco":
            pin_model = self.pin_model.copy()
            if pin_edit is not None:
                pin_model = pin_edit(pin_model)
        source = ModelSource(
            self.source.name,
            self.source.robot_file,
            self.source.scene_file,
            self.source.origin,
            (*self.source.edits, description),
            self.source.analytic,
            self.source.roots,
        )
        return Robot(source, pin_model, spec)

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nq={self.nq}, nv={self.nv}, nu={self.nu})"


def _lookup(kind: str, table: Mapping[str, _T], name: str) -> _T:
    try:
        return table[name]
    except KeyError:
        raise UnknownNameError(kind, name, table) from None
