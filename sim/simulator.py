"""The MuJoCo plant behind the robot API: stepping, commands, state, sensors, poses, warnings.

State is exposed in Pinocchio's convention (see ``mbctl.robots.conventions``). Derived
quantities (site and body poses, sensors, contacts) are brought up to date with ``mj_forward``
on first read after a step, so they always correspond to the current state without paying for
a forward pass on every step.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Literal, Protocol

import mujoco
import numpy as np
import numpy.typing as npt

from mbctl.robots.command_binding import CommandBinder
from mbctl.robots.commands import Command
from mbctl.robots.exceptions import CommandOutOfRange
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_report import LinkReport, PlantReport, SafetyReport, TimingReport
from mbctl.sim.exceptions import SimError, SimulationDiverged

#: MuJoCo warnings after which the run cannot be trusted: bad qpos/qvel/qacc mean the
#: integration diverged and MuJoCo reset the state; bad ctrl means MuJoCo zeroed the controls
#: (a |ctrl| above mjMAXVAL). All of them are silent in MuJoCo; the simulator raises.
DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADCTRL,
)
_DIVERGENCE_IDS = tuple(int(w) for w in DIVERGENCE_WARNINGS)
_WARNING_NAMES = {
    int(w): name.removeprefix("mjWARN_")
    for name, w in mujoco.mjtWarning.__members__.items()
    if name != "mjNWARNING"
}


class Perturbation(Protocol):
    """Acts on the plant before each physics step (e.g. :class:`~mbctl.sim.perturb.PushSchedule`)."""

    def apply(self, data: mujoco.MjData) -> object:
        """Write this step's external forces into ``data`` (e.g. ``xfrc_applied``)."""


class Simulator:
    """Steps a robot's MuJoCo model and implements :class:`~mbctl.robots.interface.RobotInterface`.

    Out-of-range commands: a value outside an actuator's ctrlrange is clamped to the range (as
    MuJoCo itself does for limited actuators) and counted per actuator in ``saturation_counts``;
    with ``out_of_range="raise"`` it raises :class:`CommandOutOfRange` instead.

    Args:
        robot: The model pair; the simulator owns a fresh ``MjData`` of ``robot.mj_model``.
        control_period_s: Period [s] of ``sync()``; an integer multiple of the timestep
            (default: one timestep).
        out_of_range: "clamp" (default) or "raise".

    Raises:
        SimError: A control period that is not a positive integer multiple of the timestep.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        control_period_s: float | None = None,
        out_of_range: Literal["clamp", "raise"] = "clamp",
    ):
        self._robot = robot
        self.model = robot.mj_model
        self.data = mujoco.MjData(self.model)
        dt = self.model.opt.timestep
        period = dt if control_period_s is None else float(control_period_s)
        ratio = period / dt
        if period <= 0 or abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
            raise SimError(
                f"control_period_s={period} must be a positive integer multiple of the timestep "
                f"{dt} s (e.g. {dt * max(1, round(ratio))})"
            )
        if out_of_range not in ("clamp", "raise"):
            raise SimError(f"out_of_range must be 'clamp' or 'raise'; got {out_of_range!r}")
        self.n_substeps = int(round(ratio))
        self._out_of_range = out_of_range
        self._binder = CommandBinder(robot)
        self._conv = robot.converter
        # The robot's coordinates in qpos and qvel (the plant may hold scene coordinates too).
        self._qi, self._vi = robot.qpos_index, robot.qvel_index
        self.n_steps = 0
        self._last_command: Command | None = None
        self._stale = True
        self._ctrl = self.data.ctrl  # views into MjData, bound once for the hot path
        # the robot's qpos and qvel as views when its coordinates are contiguous (the usual
        # case; slicing MjData on each read costs as much as the conversion), else None: gathered
        self._qpos_view = self.data.qpos[self._qi] if isinstance(self._qi, slice) else None
        self._qvel_view = self.data.qvel[self._vi] if isinstance(self._vi, slice) else None
        self._warn_numbers = self.data.warning.number
        self._warn_seen = self._warn_numbers.tolist()
        self._t_step = 0.0  # time [s] at the last step_begin
        self._observers: tuple[Callable[[Simulator], None], ...] = ()
        self._perturbations: tuple[Perturbation, ...] = ()
        #: Wall time [s] of the last ``sync``'s physics (MuJoCo's steps and the perturbations).
        self.physics_time_s = 0.0
        #: Simulated time [s] when the last ``sync``/``step``/``hold`` began: the time of the state its
        #: command saw, the same float (``time_s + period - period`` need not be).
        self.period_start_s = 0.0
        self.reset()

    def add_observer(self, observer: Callable[[Simulator], None]) -> None:
        """Call ``observer(sim)`` after every ``step()`` and ``sync()`` (video, trajectories, viewers).

        Observers read the plant; they must not change its state. With none (the default) a step
        costs nothing extra.
        """
        self._observers = (*self._observers, observer)

    def remove_observer(self, observer: Callable[[Simulator], None]) -> None:
        """Stop calling ``observer`` (no-op if it is not registered)."""
        self._observers = tuple(o for o in self._observers if o is not observer)

    def add_perturbation(self, perturbation: Perturbation) -> None:
        """Call ``perturbation.apply(data)`` before every physics step (external forces, pushes).

        With perturbations, the period's substeps run one by one so each sees its own time.
        """
        self._perturbations = (*self._perturbations, perturbation)

    # ------------------------------------------------------------------ RobotInterface
    @property
    def robot(self) -> Robot:
        """The model pair."""
        return self._robot

    @property
    def control_period_s(self) -> float:
        """Duration [s] of one ``sync()``."""
        return self.n_substeps * self.model.opt.timestep

    @property
    def time_s(self) -> float:
        """Simulated time [s]."""
        return float(self.data.time)

    def read_state(self) -> RobotState:
        """Current state (q, v in Pinocchio's convention, time) as read-only copies."""
        qpos, qvel = self._qpos_view, self._qvel_view
        q, v = self._conv.state_mj_to_pin(self.data.qpos[self._qi] if qpos is None else qpos,
                                          self.data.qvel[self._vi] if qvel is None else qvel)
        q.setflags(write=False)
        v.setflags(write=False)
        # the namedtuple built as tuple.__new__ does it, without its Python-level __new__ (per cycle);
        # every field given (a tuple shorter than the type breaks its repr and its later fields)
        return tuple.__new__(RobotState, (q, v, float(self.data.time), (), self.n_steps))

    @property
    def state(self) -> RobotState:
        """Current state; same as ``read_state()``."""
        return self.read_state()

    def send(self, command: Command) -> None:
        """Write a command into ctrl; it holds until the next command.

        Raises:
            CommandError: Wrong kind, shape, or names (see ``CommandBinder``).
            CommandOutOfRange: A value outside ctrlrange when ``out_of_range="raise"``.
        """
        if command is self._last_command:
            return  # commands are immutable: the same object is already in ctrl
        b = self._binder.bind(command)
        values = command.values
        if b.limited and b.out_of_range(values):
            if self._out_of_range == "raise":
                i = int(np.flatnonzero((values < b.ctrl_low) | (values > b.ctrl_high))[0])
                name = self.model.actuator(int(b.index[i])).name
                raise CommandOutOfRange(
                    f"{command.kind.value} command {values[i]:g} for actuator {name!r} is "
                    f"outside its ctrlrange [{b.ctrl_low[i]:g}, {b.ctrl_high[i]:g}]"
                )
            values = self._binder.clamp(b, values)
        if b.full:
            self._ctrl[:] = values
        else:
            self._ctrl[b.index] = values
        self._last_command = command

    def sync(self) -> None:
        """Advance the physics by one control period (``n_substeps`` steps).

        Raises:
            SimulationDiverged: MuJoCo flagged bad qpos/qvel/qacc/ctrl during the period.
        """
        # step() inlined: this runs once per control cycle
        t0 = self.data.time  # MuJoCo restarts its clock when it resets a diverged state
        self.period_start_s = t0
        wall0 = time.perf_counter()
        if self._perturbations:
            self._perturbed_steps(self.n_substeps)
        else:
            mujoco.mj_step(self.model, self.data, self.n_substeps)
        self.physics_time_s = time.perf_counter() - wall0
        self.n_steps += self.n_substeps
        self.n_syncs += 1
        self._stale = True
        if self._warn_numbers.tolist() != self._warn_seen:  # the check, inlined: once per cycle
            self._check_divergence(t0)
        for observer in self._observers:
            observer(self)

    # ------------------------------------------------------------------ stepping
    def step(self, command: Command | None = None, n: int = 1) -> None:
        """Apply ``command`` (None keeps the current ctrl) and advance ``n`` physics steps.

        Raises:
            SimulationDiverged: MuJoCo flagged bad qpos/qvel/qacc during these steps.
        """
        if command is not None:
            self.send(command)
        if n < 1:
            raise SimError(f"n must be a positive number of steps; got {n}")
        t0 = self.period_start_s = self.data.time
        if self._perturbations:
            self._perturbed_steps(n)
        elif n == 1:
            mujoco.mj_step(self.model, self.data)
        else:
            mujoco.mj_step(self.model, self.data, n)
        self.n_steps += n
        self._stale = True
        self._check_divergence(t0)
        for observer in self._observers:
            observer(self)

    def hold(self, n: int = 1) -> None:
        """Let ``n`` physics steps of time pass with the robot held still: nothing is integrated.

        A plant waiting for its first command (a robot in its harness, the DDS bridge before the
        first LowCmd) keeps its state while its clock runs; derived quantities are those of that
        state. Observers are called as after a step; ``n_steps`` counts physics steps only.

        Raises:
            SimError: ``n`` < 1.
        """
        if n < 1:
            raise SimError(f"n must be a positive number of steps; got {n}")
        self.forward()
        self.period_start_s = self.data.time
        self.data.time += n * self.model.opt.timestep
        for observer in self._observers:
            observer(self)

    def _perturbed_steps(self, n: int) -> None:
        for _ in range(n):
            for perturbation in self._perturbations:
                perturbation.apply(self.data)
            mujoco.mj_step(self.model, self.data)

    def step_begin(self) -> None:
        """First half of one physics step (``mj_step1``): kinematics and position/velocity sensors.

        For plants that report the state a step starts from (the DDS bridge): between
        ``step_begin`` and ``step_end`` the data holds the current state's kinematics and sensors;
        ``step_end`` adds the acceleration-stage sensors (accelerometer, contact forces) of the same
        state and integrates. Together they equal ``step()`` exactly.
        """
        self._t_step = self.data.time
        mujoco.mj_step1(self.model, self.data)
        self._stale = False

    def step_end(self) -> None:
        """Second half of the step begun by ``step_begin`` (``mj_step2``): forces, integration.

        Raises:
            SimulationDiverged: MuJoCo flagged bad qpos/qvel/qacc/ctrl.
        """
        for perturbation in self._perturbations:
            perturbation.apply(self.data)
        mujoco.mj_step2(self.model, self.data)
        self.n_steps += 1
        self._stale = True
        self._check_divergence(self._t_step)
        for observer in self._observers:
            observer(self)

    def _check_divergence(self, t0: float) -> None:
        """Raise SimulationDiverged if MuJoCo flagged a divergence in the steps begun at ``t0`` [s]."""
        counts = self._warn_numbers.tolist()  # one call; cheaper than per-warning struct access
        if counts == self._warn_seen:
            return
        fired = {}
        for wid in _DIVERGENCE_IDS:
            if counts[wid] != self._warn_seen[wid]:
                fired[_WARNING_NAMES[wid]] = counts[wid] - self._warn_seen[wid]
        self._warn_seen = counts
        if fired:
            raise SimulationDiverged(fired, float(t0))

    def reset(
        self,
        keyframe: str | None = None,
        *,
        q: npt.ArrayLike | None = None,
        v: npt.ArrayLike | None = None,
    ) -> None:
        """Reset to the model's default state, a keyframe, or a given (q, v) (Pinocchio convention).

        Clears time, ctrl (or sets the keyframe's ctrl), warnings and saturation counts.
        """
        if keyframe is not None:
            mujoco.mj_resetDataKeyframe(self.model, self.data, self._robot.keyframe_id(keyframe))
        else:
            mujoco.mj_resetData(self.model, self.data)
        if q is not None or v is not None:
            self.set_state(
                q if q is not None else self.q,
                v if v is not None else np.zeros(self._robot.nv),
            )
        self._binder.reset_counts()
        self.n_syncs = 0
        self.n_steps = 0
        self._last_command = None
        self._warn_seen = self._warn_numbers.tolist()
        self.period_start_s = float(self.data.time)
        self._forward()

    def set_state(self, q: npt.ArrayLike, v: npt.ArrayLike) -> None:
        """Set the robot's q (nq,) and v (nv,) in Pinocchio's convention, keeping time and ctrl.

        The scene's coordinates (a free box) are left as they are.
        """
        q_pin = self._conv.check_q(q)
        v_pin = self._conv.check_v(v)
        self.data.qpos[self._qi] = self._conv.q_pin_to_mj(q_pin)
        self.data.qvel[self._vi] = self._conv.v_pin_to_mj(q_pin, v_pin)
        self._forward()

    # ------------------------------------------------------------------ state
    @property
    def q(self) -> np.ndarray:
        """Configuration (nq,), Pinocchio convention (copy)."""
        return self._conv.q_mj_to_pin(self.data.qpos[self._qi])

    @property
    def v(self) -> np.ndarray:
        """Velocity (nv,), Pinocchio convention (copy)."""
        return self._conv.state_mj_to_pin(self.data.qpos[self._qi], self.data.qvel[self._vi])[1]

    @property
    def ctrl(self) -> np.ndarray:
        """Current actuator controls (nu,) (copy)."""
        return self.data.ctrl.copy()

    def joint_q(self, name: str) -> np.ndarray:
        """Coordinates of joint ``name`` (Pinocchio convention) (copy)."""
        return self.q[self._robot.joint(name).q_slice]

    # ------------------------------------------------------------------ derived quantities
    def _forward(self) -> None:
        mujoco.mj_forward(self.model, self.data)
        self._stale = False

    def forward(self) -> None:
        """Recompute derived quantities for the current state, if a step made them stale."""
        if self._stale:
            self._forward()

    def sensor(self, name: str) -> np.ndarray:
        """Reading (dim,) of sensor ``name`` at the current state (copy)."""
        info = self._robot.sensor(name)
        self.forward()
        return self.data.sensordata[info.data_slice].copy()

    def sensors(self) -> dict[str, np.ndarray]:
        """Every sensor's reading by name (copies)."""
        self.forward()
        return {n: self.data.sensordata[s.data_slice].copy() for n, s in self._robot.sensors.items()}

    def site_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position p_WS (3,) [m] and rotation R_WS (3, 3) of site ``name`` in the world frame."""
        i = self._robot.site_id(name)
        self.forward()
        return self.data.site_xpos[i].copy(), self.data.site_xmat[i].reshape(3, 3).copy()

    def body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position p_WB (3,) [m] and rotation R_WB (3, 3) of body ``name`` in the world frame."""
        i = self._robot.body_id(name)
        self.forward()
        return self.data.xpos[i].copy(), self.data.xmat[i].reshape(3, 3).copy()

    @property
    def base_z_m(self) -> float:
        """Height [m] of the floating base (z of the free joint); NaN for a fixed base."""
        if not self._robot.has_floating_base:
            return float("nan")
        return float(self.data.qpos[next(iter(self._robot.joints.values())).qposadr + 2])

    @property
    def contact_count(self) -> int:
        """Number of active contacts at the current state."""
        self.forward()
        return int(self.data.ncon)

    @property
    def warnings(self) -> dict[str, int]:
        """MuJoCo's warning counters since the last reset, by name (only non-zero ones)."""
        return {
            _WARNING_NAMES[i]: int(self.data.warning[i].number)
            for i in _WARNING_NAMES
            if self.data.warning[i].number
        }

    def saturations(self) -> dict[str, int]:
        """How many commands were clamped to ctrlrange, per actuator name (non-zero only)."""
        return self._binder.clamped()

    @property
    def binder(self) -> CommandBinder:
        """The plant's command binder (its clamp counts are the plant's)."""
        return self._binder

    @property
    def saturation_counts(self) -> np.ndarray:
        """Values clamped to ctrlrange, per actuator (nu,)."""
        return self._binder.clamp_counts

    @property
    def saturated_commands(self) -> int:
        """Commands in which at least one value was outside its actuator's ctrlrange (clamped)."""
        return self._binder.clamped_commands

    # ------------------------------------------------------------------ lifecycle and report
    def open(self) -> Simulator:
        """Nothing to connect: the plant is ready from construction (the contract's first step)."""
        return self

    def stop(self) -> None:
        """The loop is over: nothing to keep safe in simulation (the contract's end of a loop)."""

    def close(self) -> None:
        """Nothing to leave safe in simulation; the plant stays readable (idempotent)."""

    def __enter__(self) -> Simulator:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def position_gains(self) -> dict[str, tuple[float, float]]:
        """The position actuators' (kp [N m/rad], kv [N m s/rad]), by joint name."""
        return {a.joint: (a.kp, a.kv) for a in self._robot.actuators.values() if a.kind == "position"}

    def report(self) -> PlantReport:
        """The plant's report: simulated timing (every period exact), no link, the clamp counts."""
        period_ms = self.control_period_s * 1e3
        return PlantReport(
            "sim", TimingReport(self.n_syncs, period_ms, period_ms, period_ms),
            LinkReport("direct"),
            SafetyReport(self._binder.clamped(), self._binder.clamped_commands))


