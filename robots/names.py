"""Name maps of a MuJoCo model: actuators, sensors, keyframes — derived once at load time."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

#: What an actuator's ctrl means, from its gain and bias (whatever the transmission: joint,
#: tendon, site). "other": neither a force nor a target (muscles, activation dynamics, gains that
#: vary); such actuators take ``robots.commands.ctrl`` commands, as every actuator does.
ACTUATOR_KINDS = ("torque", "position", "velocity", "other")


@dataclass(frozen=True)
class ActuatorInfo:
    """One MuJoCo actuator.

    Attributes:
        name: Actuator name.
        index: Index in ``MjData.ctrl``.
        joint: Name of the driven joint ("" for non-joint transmissions).
        kind: "torque" (motor: force = gear * ctrl), "position" (ctrl sets a target of the
            transmission's length [rad] or [m]), "velocity" (ctrl is a target [rad/s] or [m/s])
            or "other".
        gear: Transmission gear.
        kp: Position gain [N m/rad] for position actuators, else 0.
        kv: Velocity gain [N m s/rad] for position/velocity actuators, else 0.
        ctrl_range: (low, high) of ctrl, or (-inf, inf) when not limited.
        force_range: (low, high) of the actuator force [N m] or [N], or (-inf, inf).
        transmission: What the actuator drives: "joint NAME", "tendon NAME", "site NAME" or
            "body NAME".
        target_per_ctrl: For position actuators, target = target_per_ctrl * ctrl: 1 for MuJoCo's
            ``<position>``; a general actuator may scale (a gripper's ctrl 0..255 -> 0..0.8).
    """

    name: str
    index: int
    joint: str
    kind: str
    gear: float
    kp: float
    kv: float
    ctrl_range: tuple[float, float]
    force_range: tuple[float, float]
    transmission: str = ""
    target_per_ctrl: float = 1.0


@dataclass(frozen=True)
class SensorInfo:
    """One MuJoCo sensor: name, type name (e.g. "gyro"), dimension and address in sensordata."""

    name: str
    type: str
    dim: int
    adr: int

    @property
    def data_slice(self) -> slice:
        """Slice of ``MjData.sensordata`` holding this sensor."""
        return slice(self.adr, self.adr + self.dim)


_PREFIX = {mujoco.mjtObj.mjOBJ_BODY: "body", mujoco.mjtObj.mjOBJ_JOINT: "joint",
           mujoco.mjtObj.mjOBJ_SITE: "site", mujoco.mjtObj.mjOBJ_ACTUATOR: "actuator",
           mujoco.mjtObj.mjOBJ_SENSOR: "sensor", mujoco.mjtObj.mjOBJ_KEY: "key",
           mujoco.mjtObj.mjOBJ_GEOM: "geom"}


def mj_name(m: mujoco.MjModel, objtype: mujoco.mjtObj, i: int) -> str:
    """The name of MuJoCo object ``i``; an unnamed one is ``<kind><id>`` (``body3``, ``joint0``).

    The one naming rule of the toolkit: the Pinocchio model built from ``m`` uses it for its
    joints and frames, so both engines address unnamed objects alike.
    """
    return mujoco.mj_id2name(m, objtype, i) or f"{_PREFIX[objtype]}{i}"


def _name(m: mujoco.MjModel, objtype: mujoco.mjtObj, i: int) -> str:
    return mujoco.mj_id2name(m, objtype, i) or ""


def actuator_infos(m: mujoco.MjModel) -> dict[str, ActuatorInfo]:
    """Every named actuator of ``m``, classified by what its ctrl means."""
    out: dict[str, ActuatorInfo] = {}
    for i in range(m.nu):
        name = _name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}"
        joint = ""
        trn = mujoco.mjtTrn(int(m.actuator_trntype[i]))
        if trn in (mujoco.mjtTrn.mjTRN_JOINT, mujoco.mjtTrn.mjTRN_JOINTINPARENT):
            jid = int(m.actuator_trnid[i, 0])
            joint = _name(m, mujoco.mjtObj.mjOBJ_JOINT, jid)
        kind, kp, kv, scale = _classify(m, i)
        ctrl = tuple(m.actuator_ctrlrange[i]) if m.actuator_ctrllimited[i] else (-np.inf, np.inf)
        force = (-np.inf, np.inf)
        if m.actuator_forcelimited[i]:
            force = tuple(m.actuator_forcerange[i])
        if joint:
            jid = int(m.actuator_trnid[i, 0])
            if m.jnt_actfrclimited[jid]:
                lo, hi = m.jnt_actfrcrange[jid]
                force = (max(force[0], lo), min(force[1], hi))
        out[name] = ActuatorInfo(
            name=name,
            index=i,
            joint=joint,
            kind=kind,
            gear=float(m.actuator_gear[i, 0]),
            kp=kp,
            kv=kv,
            ctrl_range=(float(ctrl[0]), float(ctrl[1])),
            force_range=(float(force[0]), float(force[1])),
            transmission=_transmission(m, i, trn),
            target_per_ctrl=scale,
        )
    return out


_TRN_OBJECT = {
    mujoco.mjtTrn.mjTRN_JOINT: ("joint", mujoco.mjtObj.mjOBJ_JOINT),
    mujoco.mjtTrn.mjTRN_JOINTINPARENT: ("joint", mujoco.mjtObj.mjOBJ_JOINT),
    mujoco.mjtTrn.mjTRN_TENDON: ("tendon", mujoco.mjtObj.mjOBJ_TENDON),
    mujoco.mjtTrn.mjTRN_SITE: ("site", mujoco.mjtObj.mjOBJ_SITE),
    mujoco.mjtTrn.mjTRN_SLIDERCRANK: ("slider-crank site", mujoco.mjtObj.mjOBJ_SITE),
    mujoco.mjtTrn.mjTRN_BODY: ("body", mujoco.mjtObj.mjOBJ_BODY),
}


def _transmission(m: mujoco.MjModel, i: int, trn: mujoco.mjtTrn) -> str:
    word, objtype = _TRN_OBJECT.get(trn, ("transmission", mujoco.mjtObj.mjOBJ_UNKNOWN))
    obj = int(m.actuator_trnid[i, 0])
    return f"{word} {_name(m, objtype, obj) or f'#{obj}'}"


def _classify(m: mujoco.MjModel, i: int) -> tuple[str, float, float, float]:
    """(kind, kp, kv, target_per_ctrl) from the gain and bias: force = gain ctrl + b0 + b1 L + b2 Ldot.

    A general actuator with a fixed gain and an affine bias with stiffness (b1 < 0) is a
    position actuator with kp = -b1, kv = -b2 and target L = (gain / kp) ctrl (a gripper).
    """
    if m.actuator_dyntype[i] != mujoco.mjtDyn.mjDYN_NONE:
        return "other", 0.0, 0.0, 1.0
    if m.actuator_gaintype[i] != mujoco.mjtGain.mjGAIN_FIXED:
        return "other", 0.0, 0.0, 1.0
    gain = float(m.actuator_gainprm[i, 0])
    bias = m.actuator_biasprm[i, :3]
    if m.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_NONE:
        return "torque", 0.0, 0.0, 1.0
    if m.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_AFFINE and bias[0] == 0 and gain > 0:
        if bias[1] < 0:
            return "position", float(-bias[1]), float(-bias[2]), gain / float(-bias[1])
        if bias[1] == 0 and np.isclose(bias[2], -gain):
            return "velocity", 0.0, gain, 1.0
    return "other", 0.0, 0.0, 1.0


def sensor_infos(m: mujoco.MjModel) -> dict[str, SensorInfo]:
    """Every sensor of ``m`` with its type name, dimension and sensordata address."""
    out: dict[str, SensorInfo] = {}
    for i in range(m.nsensor):
        name = _name(m, mujoco.mjtObj.mjOBJ_SENSOR, i) or f"sensor{i}"
        type_name = mujoco.mjtSensor(int(m.sensor_type[i])).name.removeprefix("mjSENS_").lower()
        out[name] = SensorInfo(name, type_name, int(m.sensor_dim[i]), int(m.sensor_adr[i]))
    return out


def names_of(m: mujoco.MjModel, objtype: mujoco.mjtObj, count: int) -> tuple[str, ...]:
    """Names of all objects of one type, in id order (unnamed ones as :func:`mj_name` names them)."""
    return tuple(mj_name(m, objtype, i) for i in range(count))
