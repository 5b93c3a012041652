"""The MuJoCo plant speaking the G1's low-level messages: subscribes ``rt/lowcmd``, publishes ``rt/lowstate``.

Each physics step (the G1's 2 ms, paced to wall-clock time) the bridge

1. takes the LowCmd_ messages that arrived, ignores and counts those with a bad CRC, another
   ``mode_machine``, ``mode_pr`` = 1 (the ankles' parallel-linkage mode is not modelled) or
   non-finite values, clamps the rest to the robot's ranges (gains ``kp``, ``kd`` and the velocity
   target to the table's bounds, :mod:`mbctl.unitree.tables`; the position target to the joint's
   range and the feed-forward torque to its limit, from the model) counting each clamped command
   and, per motor, each clamp of an enabled motor, and puts them on the command link (latency,
   jitter, drops);
2. applies the newest command the link delivers as the motor firmware does: each enabled motor
   exerts ``tau + kp (q* - q) + kd (dq* - dq)``, clamped to its torque limit. The law is MuJoCo's
   own actuator (force = ctrl + b1 q + b2 qdot with ctrl = tau + kp q* + kd dq*, b1 = -kp,
   b2 = -kd), so it is evaluated at every physics step, its damping integrated implicitly
   (``implicitfast``) exactly as the in-process position actuators, and clamped by the joints'
   ``actuatorfrcrange``; a disabled motor exerts nothing;
3. steps the physics, then publishes LowState_ (motor q, dq, tau_est; IMU quaternion of its site,
   gyro and accelerometer sensors plus optional noise) through the state link, ``tick`` counting
   the LowStates made;
4. records its ground truth (base pose and velocity, CoM, feet, contact forces) in a CSV row.

Until the first valid command the physics is paused (states are still published, the IMU reading
at rest), like a robot held still in its harness, so a client starts from the same pose as the
in-process run.

Lock-step (``lockstep``): the physics advances one control period per command received, no faster
than real time, and publishes one state per command (the state that step starts from, as above):
a run over DDS then gives the same result however loaded the machine is. Until the first command
the held state is published every period with one tick (1: the same state again, which a client
does not take for a new one), so a client connects, measures the rate and starts from it; each
step's state then advances the tick. No link model (delays need a wall clock).

One bridge per domain: a bridge that finds another ``rt/lowstate`` writer on its domain when it
starts (a second bridge, a robot; :data:`~mbctl.unitree.channel.DISCOVERY_S` of discovery) refuses
to start (:class:`~mbctl.unitree.exceptions.AnotherWriterError`, exit 2).

A bridge that diverges stops and says so (:class:`~mbctl.sim.exceptions.SimulationDiverged`,
exit 1): MuJoCo's divergence warnings, or an acceleration beyond :data:`MAX_QACC` (a state no
robot reaches), naming how long the last command had been applied (stale torques from a client
that went away). Its idle timeout counts from its start: a bridge nobody commands stops too.
"""

from __future__ import annotations

import gc
import subprocess
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from mbctl.robots.model_pair import Robot
from mbctl.sim.contacts import measure_contacts
from mbctl.sim.exceptions import SimError, SimulationDiverged
from mbctl.sim.imu import ImuReader
from mbctl.sim.link import DelayLine, LinkSpec
from mbctl.sim.simulator import Simulator
from mbctl.unitree.channel import DISCOVERY_S, LOOPBACK, TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel, message_types
from mbctl.unitree.clock import CycleClock, RealtimePriority
from mbctl.unitree.exceptions import WireFormatError
from mbctl.unitree.motors import MODE_PR, MOTOR_ENABLED, MotorMap
from mbctl.unitree.tables import G1_29DOF, MotorTable
from mbctl.unitree.wire import low_cmd_codec, low_state_codec

#: The start of the line ``mbctl serve`` writes first on stderr, once its bridge is up.
SERVING = "serving on DDS domain"

#: Seconds a bridge process gets to load its robot and join DDS before it is given up [s].
BRIDGE_START_S = 120.0


class BridgeStartError(SimError):
    """A bridge process (``mbctl serve``) did not start serving."""


class BridgeDiverged(SimulationDiverged):
    """The bridge's plant reached an acceleration no robot does (MuJoCo itself had not flagged it).

    Attributes:
        peak_qacc: The largest joint or base acceleration of the step [rad/s^2, m/s^2].
        stale_s: How long [s] the last command had been applied.
    """

    def __init__(self, peak_qacc: float, time_s: float, stale_s: float):
        self.peak_qacc, self.stale_s = peak_qacc, stale_s
        self.warnings, self.time_s = {"qacc": 1}, time_s
        SimError.__init__(self, (
            f"the bridge's plant diverged near t={time_s:.4f} s: an acceleration of {peak_qacc:.3g} "
            f"(beyond {MAX_QACC:g}: no robot moves so) after its last command had been applied for "
            f"{stale_s:.3f} s (stale torques from a client that went away, or a command that drives the "
            "plant apart); the bridge stops instead of serving a diverged plant"))


def wait_until_serving(process: subprocess.Popen[str], timeout_s: float = BRIDGE_START_S) -> str:
    """Block until ``process`` (``mbctl serve ...``, stderr piped as text) says it serves; that line.

    Raises:
        BridgeStartError: Its first line is another (it failed: the message holds its stderr), or
            none came within ``timeout_s`` [s] (the process is then killed).
    """
    timer = threading.Timer(timeout_s, process.kill)  # a bridge that never serves cannot hang us
    started = time.monotonic()
    timer.start()
    try:
        line = process.stderr.readline() if process.stderr is not None else ""
    finally:
        timer.cancel()
    if SERVING in line:
        return line
    rest = process.stderr.read() if process.stderr is not None else ""
    why = (f"wrote no {SERVING!r} line within {timeout_s:g} s (killed)"
           if time.monotonic() - started >= timeout_s else "did not start")
    raise BridgeStartError(f"the DDS bridge {why}: {(line + rest).strip()}")

#: The truth log measures contact forces every this many steps (measuring costs ~0.1 ms).
FORCE_EVERY = 10
#: ``mode_machine`` the bridge reports (the robot's type code; clients copy it into LowCmd_).
BRIDGE_MODE_MACHINE = 5
#: The largest joint or base acceleration [rad/s^2, m/s^2] a sane plant step gives; beyond it the
#: bridge has diverged.
MAX_QACC = 1e5


def motor_pd_actuators(robot: Robot) -> Robot:
    """The robot with each actuator turned into the motor law's actuator (gain 1, affine bias).

    ``ctrl`` is unlimited (it holds ``tau + kp q* + kd dq*``); the torque is clamped by the joints'
    ``actuatorfrcrange`` (the Menagerie G1's motor limits). The bias gains are set per command.
    """

    def edit(spec: mujoco.MjSpec) -> None:
        for act in spec.actuators:
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            act.gainprm = np.array([1.0] + [0.0] * 9)
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            act.biasprm = np.zeros(10)
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            act.inheritrange = 0
        for key in spec.keys:
            key.ctrl = np.zeros(0)

    return robot.with_edits("actuators -> motor PD law (tau + kp (q* - q) + kd (dq* - dq))", mj_edit=edit)


def command_ranges(motors: MotorMap, table: MotorTable) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per motor (n,), the (low, high) a LowCmd's fields are clamped to, as the wire's float32.

    Gains and velocity targets: the table's bounds (mbctl's, see :mod:`mbctl.unitree.tables`);
    position targets: the model's joint range; feed-forward torque: the model's torque limit.
    """
    n = motors.n

    def pair(low: npt.ArrayLike, high: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        return (np.broadcast_to(np.asarray(low, dtype=np.float32), (n,)).copy(),
                np.broadcast_to(np.asarray(high, dtype=np.float32), (n,)).copy())

    return {"kp": pair(0.0, table.kp_max), "kd": pair(0.0, table.kd_max),
            "dq": pair(-table.dq_max, table.dq_max), "q": pair(motors.q_low, motors.q_high),
            "tau": pair(-motors.tau_max, motors.tau_max)}


@dataclass(frozen=True)
class BridgeOptions:
    """Where the bridge listens and what its link does.

    Attributes:
        domain: DDS domain id.
        network_interface: ``lo`` unless a real network is meant.
        link: Latency, jitter, drops and IMU noise (applied to both directions).
        mode_machine: The ``mode_machine`` reported and required in commands.
        lockstep: One physics period per command received (see the module docstring).
        discovery_s: How long [s] the start waits for discovery to show another ``rt/lowstate``
            writer on the domain (a second bridge, a robot): the bridge then refuses to start.
    """

    domain: int = 0
    network_interface: str = LOOPBACK
    link: LinkSpec = LinkSpec()
    mode_machine: int = BRIDGE_MODE_MACHINE
    lockstep: bool = False
    discovery_s: float = DISCOVERY_S

    def __post_init__(self) -> None:
        link = self.link
        if self.lockstep and (link.latency_ms or link.jitter_ms or link.drop):
            raise SimError("a lock-step bridge advances one period per command: latency, jitter and drops "
                           "need a wall clock; leave them out, or run without --lockstep")


#: Columns of the truth log (world frame W, MuJoCo's quaternion order w, x, y, z). ``unix_s`` is the
#: wall-clock time [s since the Unix epoch] the row was made: the log's identity (ticks restart with
#: every bridge), which a client compares with when its own loop ran (``mbctl.jobs.truth``).
TRUTH_COLUMNS = (
    "tick", "time_s", "wall_s", "unix_s", "commands_applied",
    "base_x_m", "base_y_m", "base_z_m", "base_qw", "base_qx", "base_qy", "base_qz",
    "base_vx_m_s", "base_vy_m_s", "base_vz_m_s", "com_x_m", "com_y_m", "com_z_m",
    "left_foot_x_m", "left_foot_y_m", "left_foot_z_m", "right_foot_x_m", "right_foot_y_m", "right_foot_z_m",
    "left_foot_fz_N", "right_foot_fz_N",
)


class G1Bridge:
    """The G1's MuJoCo plant behind DDS (see the module docstring).

    Args:
        robot: The G1 model pair (any actuators: they are converted with :func:`motor_pd_actuators`).
        start_q: Initial configuration (nq,), Pinocchio convention.
        options: Domain, network interface, link.
        feet: Foot sites (recorded in the truth log), left then right.
        table: The robot's motor table (its slot order and the IMU LowState_ reports).

    Raises:
        ChannelError: Missing hardware extra, bad domain or unknown interface.
        AnotherWriterError: Another ``rt/lowstate`` writer on the domain (a second bridge, a robot).
        MotorTableError: A robot that does not match ``table``.
    """

    def __init__(self, robot: Robot, start_q: npt.ArrayLike, options: BridgeOptions | None = None,
                 feet: Sequence[str] = ("left_foot", "right_foot"), table: MotorTable = G1_29DOF):
        self.options = options or BridgeOptions()
        self.robot = motor_pd_actuators(robot)
        self.sim = Simulator(self.robot)
        self.sim.reset(q=start_q)
        self.motors = MotorMap.for_robot(self.robot, table)
        self._act = self.motors.actuator
        self._imu = ImuReader(self.sim, table.imu, self.options.link.imu_noise, self.options.link.seed + 1)
        rng = np.random.default_rng(self.options.link.seed)
        self._commands: DelayLine[np.ndarray] = DelayLine(self.options.link, rng)
        self._states: DelayLine[bytes] = DelayLine(self.options.link, rng)
        self._cmd, self._state = low_cmd_codec(), low_state_codec()
        st = self._state.message
        st["mode_pr"] = MODE_PR
        st["mode_machine"] = self.options.mode_machine
        st["motor_state"]["mode"][: self.motors.n] = MOTOR_ENABLED
        m = self.sim.model
        self._feet = [self.robot.site_id(f) for f in feet]
        foot_bodies = [int(m.site_bodyid[s]) for s in self._feet]
        self._foot_geoms = {str(i): [g for g in range(m.ngeom) if m.geom_bodyid[g] == b]
                            for i, b in enumerate(foot_bodies)}
        base = next(j for j in self.robot.joints.values() if j.kind == "free")
        self._base_q, self._base_v = base.qposadr, base.dofadr
        # the CoM of the robot is that of the free joint's body's subtree
        self._root = int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, base.name)])
        self._qpos_motor = np.array([self.robot.joint(j).qposadr for j in self.motors.joints])
        self._qvel_motor = np.array([self.robot.joint(j).dofadr for j in self.motors.joints])
        self._forces: list[float] | None = None
        self.counts = {"commands_received": 0, "commands_applied": 0, "bad_crc": 0, "bad_encoding": 0,
                       "wrong_mode_machine": 0, "mode_pr_ab": 0, "non_finite": 0, "commands_clamped": 0,
                       "states_published": 0}
        #: Clamps per motor (table order): commands in which an enabled motor's value was clamped.
        self.clamped = np.zeros(self.motors.n, dtype=int)
        self._ranges = command_ranges(self.motors, table)
        self.started = False
        self.peak_qacc = 0.0  # the largest |qacc| of a step so far
        self.realtime = False  # whether it served at real-time priority
        self._last_command_s = 0.0
        self.channel = Channel(self.options.domain, self.options.network_interface)
        try:
            lowcmd, lowstate = message_types()
            until = time.perf_counter() + self.options.discovery_s
            others = self.channel.writers(TOPIC_LOWSTATE, lowstate)
            self._reader = self.channel.reader(TOPIC_LOWCMD, lowcmd)
            self._writer = self.channel.writer(TOPIC_LOWSTATE, lowstate)
            others.refuse_others(1, until, "the G1 bridge (mbctl serve g1) will not start: a second bridge "
                                 "or a robot already publishes its state there, and a client would take both "
                                 "plants' states", self.options.domain, self.options.network_interface)
            others.close()
        except BaseException:
            self.channel.close()
            raise
        self.clock = CycleClock(self.sim.control_period_s)

    # ------------------------------------------------------------------ commands
    def _valid_command(self, data: bytes) -> np.ndarray | None:
        """The motor records of a LowCmd_ (a copy) if it passes every check, else None (counted)."""
        counts = self.counts
        counts["commands_received"] += 1
        try:
            ok = self._cmd.decode(data)
        except WireFormatError:
            counts["bad_encoding"] += 1
            return None
        msg = self._cmd.message
        if not ok:
            counts["bad_crc"] += 1
        elif int(msg["mode_machine"]) != self.options.mode_machine:
            counts["wrong_mode_machine"] += 1
        elif int(msg["mode_pr"]) != MODE_PR:
            counts["mode_pr_ab"] += 1
        else:
            motors = msg["motor_cmd"][: self.motors.n].copy()
            if all(np.isfinite(motors[f]).all() for f in ("q", "dq", "tau", "kp", "kd")):
                self._clamp(motors)
                return motors
            counts["non_finite"] += 1
        return None

    def _clamp(self, motors: np.ndarray) -> None:
        """Clamp each field of the motor records to its range in place; count the clamps of enabled motors."""
        hit = np.zeros(self.motors.n, dtype=bool)
        for field, (low, high) in self._ranges.items():
            values = motors[field]
            clipped = np.clip(values, low, high)
            hit |= clipped != values
            motors[field] = clipped
        hit &= motors["mode"] == MOTOR_ENABLED
        if hit.any():
            self.clamped += hit
            self.counts["commands_clamped"] += 1

    def _apply(self, motors: np.ndarray) -> None:
        """Set each motor's law: ctrl = tau + kp q* + kd dq*, bias = (-kp, -kd); disabled: nothing."""
        on = motors["mode"] == MOTOR_ENABLED
        kp = np.where(on, motors["kp"], 0.0)
        kd = np.where(on, motors["kd"], 0.0)
        m = self.sim.model
        m.actuator_biasprm[self._act, 1] = -kp
        m.actuator_biasprm[self._act, 2] = -kd
        ctrl = motors["tau"] + kp * motors["q"] + kd * motors["dq"]
        self.sim.data.ctrl[self._act] = np.where(on, ctrl, 0.0)
        self.counts["commands_applied"] += 1

    # ------------------------------------------------------------------ state and truth
    def _publish_state(self, now: float) -> int:
        """Fill and send the LowState_ of the state the step started from (read between its halves)."""
        msg = self._state.message
        tick = int(msg["tick"])
        if self.started or not self.options.lockstep or tick == 0:  # lock-step: held is one state
            tick += 1
        msg["tick"] = tick
        ms = msg["motor_state"]
        n = self.motors.n
        d = self.sim.data
        ms["q"][:n] = self._q_start
        ms["dq"][:n] = self._v_start
        ms["tau_est"][:n] = d.actuator_force[self._act]
        # held still before the first command: no rotation, the specific force is -g
        imu = self._imu.imu(forward=False) if self.started else self._imu.at_rest(forward=False)
        msg["imu_state"]["quaternion"] = imu.quat_wxyz
        msg["imu_state"]["gyroscope"] = imu.gyro_I
        msg["imu_state"]["accelerometer"] = imu.accel_I
        self._states.send(now, self._state.encode())
        return tick

    def truth_row(self, tick: int, wall_s: float) -> list[float]:
        """The plant's true state at the start of the last step, as a row of :data:`TRUTH_COLUMNS`.

        Contact forces are measured every :data:`FORCE_EVERY` steps and held in between.
        """
        m, d = self.sim.model, self.sim.data
        if tick % FORCE_EVERY == 1 or self._forces is None:
            forces = measure_contacts(m, d, self._foot_geoms)
            self._forces = [forces["0"].normal_n, forces["1"].normal_n]
        feet = np.concatenate([d.site_xpos[s] for s in self._feet])
        return [tick, self._t_start, wall_s, time.time(), self.counts["commands_applied"], *self._base_start,
                *d.subtree_com[self._root], *feet, *self._forces]

    # ------------------------------------------------------------------ loop
    def step(self, now: float, command: np.ndarray | None = None) -> int:
        """One period: commands in, physics (once started), state out; the tick published.

        The LowState carries the state the physics step starts from (the plant's present); the step
        then advances it to the next period. Between its two halves (``Simulator.step_begin`` and
        ``step_end``) MuJoCo holds that state's kinematics and sensors, so no extra forward pass.

        Args:
            now: Time [s] since the bridge started.
            command: Lock-step: the command this step applies; None takes the ones that arrived and
                applies the newest the link delivers.

        Raises:
            SimulationDiverged: MuJoCo's divergence warnings, or an acceleration beyond :data:`MAX_QACC`.
        """
        if command is None:
            for data in self._reader.take(32):
                motors = self._valid_command(data)
                if motors is not None:
                    self._commands.send(now, motors)
            command = self._commands.receive(now)
        if command is not None:
            self._apply(command)
            self.started = True
            self._last_command_s = now
        sim, d = self.sim, self.sim.data
        if self.started:
            sim.step_begin()
        else:
            sim.forward()  # paused: the same state every period (computed once)
        self._q_start = d.qpos[self._qpos_motor]
        self._v_start = d.qvel[self._qvel_motor]
        self._base_start = [*d.qpos[self._base_q:self._base_q + 7], *d.qvel[self._base_v:self._base_v + 3]]
        self._t_start = float(d.time)
        if self.started:
            sim.step_end()
            self._check(now)
        tick = self._publish_state(now)
        for _ in range(64):
            payload = self._states.receive(now)
            if payload is None:
                break
            self._writer.write(payload)
            self.counts["states_published"] += 1
        return tick

    def _check(self, now: float) -> None:
        """Raise :class:`BridgeDiverged` if the step's acceleration is beyond a robot's."""
        peak = float(np.abs(self.sim.data.qacc).max())
        self.peak_qacc = max(self.peak_qacc, peak)
        if not peak <= MAX_QACC:  # NaN too
            raise BridgeDiverged(peak, self._t_start, now - self._last_command_s)

    def serve(self, duration_s: float | None = None, idle_timeout_s: float | None = None,
              on_step: Callable[[int, float], None] | None = None) -> str:
        """Run until ``duration_s`` of wall time, or ``idle_timeout_s`` without a command.

        Args:
            duration_s: Stop after this long [s] (None: until interrupted).
            idle_timeout_s: Stop once no command has arrived for this long [s], counted from the
                last command or, before any, from the start.
            on_step: Called with (tick, wall time [s]) after each period (e.g. the truth log).

        Returns:
            Why it stopped: "duration" or "idle".

        Raises:
            SimulationDiverged: The plant diverged (see :meth:`step`).
        """
        realtime = RealtimePriority()
        self.realtime = realtime.acquire()  # the bridge's own pacing counts too (where permitted)
        try:
            return self._serve(duration_s, idle_timeout_s, on_step)
        finally:
            realtime.release()

    def _serve(self, duration_s: float | None, idle_timeout_s: float | None,
               on_step: Callable[[int, float], None] | None) -> str:
        gc.freeze()  # a collection in the loop scans only what the loop made
        t0 = self.clock.start()
        last_applied, last_change = 0, t0
        while True:
            now = time.perf_counter()
            if self.options.lockstep and self.started:
                ends = [t for t in (duration_s, idle_timeout_s and last_change - t0 + idle_timeout_s) if t]
                steps = self._lockstep(t0, min([*ends, now - t0 + 0.1]) - (now - t0))
            else:
                steps = [(self.step(now - t0), now - t0)]
            for tick, wall_s in steps:
                if on_step is not None:
                    on_step(tick, wall_s)
            now = time.perf_counter()
            applied = self.counts["commands_applied"]
            if applied != last_applied:
                last_applied, last_change = applied, now
            if duration_s is not None and now - t0 >= duration_s:
                return "duration"
            if idle_timeout_s is not None and now - last_change >= idle_timeout_s:
                return "idle"
            if not (self.options.lockstep and self.started):
                self.clock.wait()

    def _lockstep(self, t0: float, wait_s: float) -> list[tuple[int, float]]:
        """Wait up to ``wait_s`` [s] for commands; one step for each, no faster than real time."""
        steps: list[tuple[int, float]] = []
        if not self._reader.wait(max(0.0, wait_s)):
            return steps
        for data in self._reader.take(32):
            motors = self._valid_command(data)
            if motors is not None:
                self.clock.wait()  # a client slower than the period counts a miss here
                wall_s = time.perf_counter() - t0
                steps.append((self.step(wall_s, motors), wall_s))
        return steps

    def stats(self) -> dict[str, Any]:
        """What the bridge counted: messages, clamps (per motor: joint -> commands), link drops, periods."""
        clamped = {j: int(c) for j, c in zip(self.motors.joints, self.clamped, strict=True) if c}
        return {**self.counts, "clamped_per_motor": clamped, "steps": self.sim.n_steps,
                "simulated_time_s": self.sim.time_s,
                "lockstep": self.options.lockstep, "peak_qacc": self.peak_qacc, "realtime": self.realtime,
                "commands_lost_by_link": self._commands.dropped,
                "states_lost_by_link": self._states.dropped, **asdict(self.clock.stats())}

    def close(self) -> None:
        """Leave DDS (idempotent)."""
        if self.channel is not None:
            self.channel.close()
            self.channel = None  # type: ignore[assignment]
