"""What the plant did in each control period, sampled without an extra forward pass (a simulator observer).

Right after ``mj_step`` MuJoCo's data holds two times at once: qpos/qvel are the new state
(t + dt), while everything the step's forward pass computed (body and site positions, the
subtree CoMs, the contacts and the forces the constraint solver applied during the step) belongs
to the step's start t. A :class:`PlantMonitor` reads the latter after every ``sync()``, so each
control cycle gets, for the state its command was computed from (time t): the robot's CoM and
the sites MuJoCo placed, the contact forces that MuJoCo applied on groups of geoms (e.g. each
foot) while executing the command, which robot bodies touch the floor, and whether the robot has
fallen, without a second ``mj_forward`` (that would cost as much as the step itself on the G1).
On request it also samples what an identification log records: the torque the actuators applied
to named joints over the period, the contact wrench on named bodies (a foot force sensor), and
the contacts on the robot elsewhere.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mbctl.robots.collision import body_geoms
from mbctl.robots.indexing import as_slice
from mbctl.robots.scene import BodiesCom
from mbctl.sim.contacts import (
    ContactSensor,
    FloorContacts,
    FloorSensors,
    MeasuredContact,
    contact_wrenches,
    contacts_elsewhere,
    measured,
    sensors_on,
)
from mbctl.sim.exceptions import SimError
from mbctl.sim.simulator import Simulator

#: ``rule(base_z_m, floor_bodies) -> reason`` or None (e.g. ``mbctl.robots.g1.G1_FALL.reason``).
FallRule = Callable[[float, Sequence[str]], "str | None"]


class PlantSample(NamedTuple):
    """One control period as a :class:`PlantMonitor` read it (immutable: keep it, convert it later).

    Attributes:
        time_s: Start time [s] of the period (the state its command saw).
        com_W: Robot CoM (3,) [m] at ``time_s``.
        site_array_W: The sampled sites' positions (s, 3) [m].
        contact_net: The contact groups' net contacts, as read
            (:meth:`ContactSensor.net <mbctl.sim.contacts.ContactSensor.net>`; empty without groups):
            the array read from MuJoCo's sensors, or the list of the contacts' loop.
        physics_time_s: Wall time [s] of the period's physics (MuJoCo's steps; the last ``sync``'s).
    """

    time_s: float
    com_W: np.ndarray
    site_array_W: np.ndarray
    contact_net: Sequence[float]
    physics_time_s: float


class PlantMonitor:
    """Samples the plant after each control period; attach with ``sim.add_observer(monitor)``.

    Args:
        sim: The plant.
        contact_groups: Geom ids per name (e.g. a foot's collision geoms) whose contact force is
            measured each period.
        sites: Robot sites whose world positions are sampled each period.
        fall_rule: Decides from the base height and the bodies touching the floor whether the
            robot has fallen (needs a floating base); the first fall is latched.
        joints: Joints whose actuator torque is sampled each period.
        wrench_bodies: Robot bodies whose contact wrench (on their colliding geoms, about their
            origin) is measured each period.
        count_elsewhere: Count each period the contacts on the robot through geoms outside the
            contact groups and the wrench bodies (self-collisions, a knee on the floor).

    Raises:
        SimError: A fall rule for a fixed-base robot.
        UnknownNameError: An unknown site, joint or body.

    Attributes:
        sample: The last period, as read (:class:`PlantSample`); the properties below are its.
        time_s: Start time [s] of the last period sampled (the state its command saw).
        contacts: Measured contact per group over the last period (world frame).
        com_W: Robot CoM (3,) [m] at ``time_s`` (its bodies' masses at MuJoCo's ``xipos``; MuJoCo's
            ``subtree_com`` of its root when the robot is that root's whole subtree).
        site_positions_W: Position (3,) [m] of each sampled site at ``time_s``.
        floor_bodies: Robot bodies touching the floor at ``time_s``.
        fall_reason: Why the robot fell (None while it has not), with ``fall_time_s`` [s].
        joint_torques: The actuators' torque (n,) [N m] on each of ``joints`` over the period
            (MuJoCo's ``qfrc_actuator``: clamped, geared; [N] on a slide joint).
        touching: Whether each wrench body touches something (c,).
        wrenches_W: Contact wrench on each wrench body (c, 6): force [N], then moment [N m] about
            the body's origin, world axes.
        contacts_elsewhere: The number of contacts counted by ``count_elsewhere`` (0 without it).
        contact_sums: Per contact group, in ``contact_groups`` order, what ``contacts`` reports as
            plain numbers: ``[fx, fy, fz, fz x, fz y, n]`` (force [N] in W, fz times the centre of
            pressure's x, y [N m], count; :meth:`ContactSensor.sums <mbctl.sim.contacts.ContactSensor.sums>`),
            for a loop that reads them every period without building ``contacts``.
        site_array_W: The sampled sites' positions (s, 3) [m] in ``sites`` order (a new array each
            period; ``site_positions_W`` is the same by name).
    """

    def __init__(self, sim: Simulator, contact_groups: Mapping[str, Iterable[int]] | None = None,
                 sites: Sequence[str] = (), fall_rule: FallRule | None = None, *,
                 joints: Sequence[str] = (), wrench_bodies: Sequence[str] = (),
                 count_elsewhere: bool = False):
        self.sim = sim
        m, robot = sim.model, sim.robot
        self._sensor = ContactSensor(m, contact_groups) if contact_groups else None
        #: The contact groups' names, the order of ``contact_sums``.
        self.group_names: tuple[str, ...] = self._sensor.names if self._sensor is not None else ()
        self._roots = [b for b in robot.robot_body_ids if int(m.body_parentid[b]) == 0]
        self._com = BodiesCom(m, robot.robot_body_ids)
        # one root whose subtree is the robot: MuJoCo's step already computed its CoM (subtree_com)
        self._subtree_com = robot.tree_root_id is not None
        #: The robot's mass [kg] in the plant.
        self.mass_kg = self._com.mass_kg
        self._site_ids = {name: robot.site_id(name) for name in sites}
        #: The sampled sites' names, the order of ``site_array_W``.
        self.site_names: tuple[str, ...] = tuple(self._site_ids)
        self._site_index = np.array(list(self._site_ids.values()), dtype=int)
        self._floor = FloorContacts(m, np.flatnonzero(m.geom_bodyid == 0), bodies=robot.robot_body_ids)
        # where MuJoCo counts the floor's contacts (robots.edits.add_floor_sensors) and sums the groups'
        # (or there are none), one read of sensordata gives both: no contact's geom pair read
        root = robot.tree_root_id
        floor = FloorSensors(m, root, robot.robot_body_ids) if root is not None else None
        nets = self._sensor.sensor_index if self._sensor is not None else np.zeros(0, dtype=int)
        self._floor_sensors = floor if floor is not None and floor.index is not None else None
        self._read = (np.concatenate([nets, floor.index]) if floor is not None and floor.index is not None
                      and nets is not None else None)
        self._n_net = 0 if nets is None else len(nets)
        self._counts_seen: list[float] | None = None  # the last counts the sensors answered for
        self._sensordata, self._opt = sim.data.sensordata, m.opt  # a view, and the options (live)
        if fall_rule is not None and not robot.has_floating_base:
            raise SimError(f"a fall rule needs a floating base; {robot.name!r} has a fixed base")
        self._fall_rule = fall_rule
        # views into MjData read every period, bound once (MjData's arrays stay where they are)
        self._root_com = sim.data.subtree_com[self._roots[0]]
        self._root_pos = sim.data.xpos[self._roots[0]]
        self._site_xpos = sim.data.site_xpos
        # before the first period: zero sums, no contacts nor sites by name
        self.sample = PlantSample(float(sim.data.time), np.zeros(3), np.zeros((len(self.site_names), 3)),
                                  [], 0.0)
        self._sums: list[list[float]] | None = [[0.0, 0.0, 0.0, 0.0, 0.0, 0] for _ in self.group_names]
        self._contacts: dict[str, MeasuredContact] | None = {}
        self._sites: dict[str, np.ndarray] | None = {}
        self.floor_bodies: tuple[str, ...] = ()
        # the contacts' geom pairs floor_bodies is from (None: from the floor sensors' counts)
        self._floor_geoms: list[list[int]] | None = []
        self.fall_reason: str | None = None
        self.fall_time_s: float | None = None
        self.base_z_m = float("nan")
        layouts = [robot.joint(j) for j in joints]
        multi = [j.name for j in layouts if j.nv != 1]
        if multi:
            raise SimError(f"joint torques are sampled on one-dof joints (hinge, slide); {multi} are not")
        self._dofs = as_slice([j.dofadr for j in layouts]) if layouts else None
        self.joint_torques = np.zeros(len(joints))
        self._wrench_ids = [robot.body_id(b) for b in wrench_bodies]
        self._wrench_groups = [body_geoms(m, b) for b in self._wrench_ids]
        self.touching = np.zeros(len(wrench_bodies), dtype=bool)
        self.wrenches_W = np.zeros((len(wrench_bodies), 6))
        self._count_elsewhere = count_elsewhere
        grouped = [g for group in (*(contact_groups or {}).values(), *self._wrench_groups) for g in group]
        self._allowed = sorted({int(g) for g in grouped})
        self.contacts_elsewhere = 0

    @property
    def time_s(self) -> float:
        """Start time [s] of the last period sampled (the state its command saw)."""
        return self.sample.time_s

    @property
    def com_W(self) -> np.ndarray:
        """Robot CoM (3,) [m] at ``time_s``."""
        return self.sample.com_W

    @property
    def site_array_W(self) -> np.ndarray:
        """The sampled sites' positions (s, 3) [m] in ``sites`` order (a new array each period)."""
        return self.sample.site_array_W

    @property
    def contact_sums(self) -> list[list[float]]:
        """Per contact group: ``[fx, fy, fz, fz x, fz y, n]`` (see the class), converted when first read."""
        if self._sums is None:
            self._sums = self.sums_of(self.sample)
        return self._sums

    def sums_of(self, sample: PlantSample) -> list[list[float]]:
        """``contact_sums`` of any period's sample (e.g. one kept to be recorded later)."""
        if self._sensor is None:
            return []
        return self._sensor.sums_from(sample.contact_net)

    @property
    def contacts(self) -> dict[str, MeasuredContact]:
        """Measured contact per group over the last period (world frame), built when first read."""
        if self._contacts is None:
            self._contacts = measured(self.group_names, self.contact_sums)
        return self._contacts

    @property
    def site_positions_W(self) -> dict[str, np.ndarray]:
        """Position (3,) [m] of each sampled site at ``time_s``, by name, built when first read."""
        if self._sites is None:
            self._sites = dict(zip(self.site_names, self.site_array_W, strict=True))
        return self._sites

    def attach(self) -> PlantMonitor:
        """Register as the simulator's observer; returns self."""
        self.sim.add_observer(self)
        return self

    def _floor_bodies_now(self, d: mujoco.MjData, geoms: list[list[int]] | None,
                          counts: list[float] | None) -> None:
        """``floor_bodies`` from the floor's contact counts, or else from the contacts' geom pairs."""
        floor = self._floor_sensors.bodies(counts) if counts is not None else None  # type: ignore[union-attr]
        if floor is not None:  # the counts name them: no other robot body is on the floor
            self.floor_bodies, self._counts_seen, self._floor_geoms = floor, counts, None
            return
        self._counts_seen = None
        if geoms is None:
            geoms = d.contact.geom.tolist() if d.ncon else []
        if geoms != self._floor_geoms:  # the bodies on the floor follow from the geom pairs alone
            self.floor_bodies = tuple(self._floor.bodies(d, geoms))
            self._floor_geoms = geoms

    def __call__(self, sim: Simulator) -> None:
        """Sample the period that just ran (the simulator calls this after every ``sync``/``step``)."""
        d = sim.data
        # the per-period hot path: plain lists, no numpy temporaries, nothing converted before the
        # caller reads it; the contacts' geom pairs read at most once, for the groups and the floor
        geoms: list[list[int]] | None = None
        counts: list[float] | None = None
        net: Sequence[float]
        if self._read is not None and sensors_on(self._opt):
            taken = self._sensordata.take(self._read)
            # the net contacts kept as the array read (a log stacks many periods' in one call), the
            # counts as plain numbers for the floor's bodies below
            net, counts = taken[:self._n_net], taken[self._n_net:].tolist()
        else:
            geoms = d.contact.geom.tolist() if d.ncon else []
            net = self._sensor.net(d, geoms) if self._sensor is not None else []
        # built as tuple.__new__ does it, without the NamedTuple's Python-level __new__ (per period)
        self.sample = tuple.__new__(PlantSample, (
            sim.period_start_s,  # the state's own time, the same float (t + T - T need not be t)
            self._root_com.copy() if self._subtree_com else self._com(d),
            self._site_xpos.take(self._site_index, 0),  # take: half a fancy index's time
            net, sim.physics_time_s))
        self._sums = self._contacts = self._sites = None
        if counts is None or counts != self._counts_seen:
            self._floor_bodies_now(d, geoms, counts)
        if self._fall_rule is not None and self.fall_reason is None:
            # the base height at the step's start: the free joint sits at the root body's origin
            self.base_z_m = float(self._root_pos[2])
            reason = self._fall_rule(self.base_z_m, self.floor_bodies)
            if reason is not None:
                self.fall_reason, self.fall_time_s = reason, self.sample.time_s
        if self._dofs is not None:
            self.joint_torques = np.array(d.qfrc_actuator[self._dofs])
        if self._wrench_ids:
            self.touching, self.wrenches_W = contact_wrenches(sim.model, d, self._wrench_groups,
                                                              d.xpos[self._wrench_ids])
        if self._count_elsewhere:
            self.contacts_elsewhere = contacts_elsewhere(sim.model, d, sim.robot.robot_body_ids,
                                                         self._allowed)
