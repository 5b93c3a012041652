"""A communication link's latency, jitter, drops and sensor noise, for the bridge and in-process.

:class:`LinkSpec` says what the link does; :class:`DelayLine` applies it to a stream of messages
in either direction; :class:`LinkedSimulator` wraps the in-process simulator in the same link, so
a robustness study runs at simulation speed and in sweeps (``--param latency_ms=0,2,5,10``)
while the bridge (``mbctl serve g1``) applies the very same model to real DDS traffic.

Semantics (each direction, state and command, independently): a message is dropped with
probability ``drop``; otherwise it arrives ``latency_ms + U(0, jitter_ms)`` after it was sent. The
receiver keeps the newest message that has arrived (an older one arriving after a newer one is
discarded, as a robot keeps its latest command). Delivery happens at the physics step, so delays
are rounded up to the plant's timestep (2 ms for the G1).

Until the first command arrives through the link the plant is held still, as the bridge holds
its physics until the first valid LowCmd: its clock runs, its state stays the start state, and
the states it sends say so (the IMU at rest). Without the hold a plant behind a latency of L
would run the first L of the run with no command at all (zero torque: a G1 sags).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, replace
from typing import Generic, TypeVar

import numpy as np

from mbctl.robots.commands import Command
from mbctl.robots.interface import BaseStateEstimator, ImuSpec, RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_report import LinkReport, PlantReport
from mbctl.sim.exceptions import SimError
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator

T = TypeVar("T")


@dataclass(frozen=True)
class LinkSpec:
    """What the link between controller and plant does.

    Attributes:
        latency_ms: Delay of every message, each direction [ms].
        jitter_ms: Extra delay, uniform in [0, jitter_ms] [ms].
        drop: Probability that a message is lost, each direction [-].
        imu_noise: Gyro and accelerometer noise, as a multiple of the model's declared noise.
        seed: Seed of the drops, jitter and noise.
    """

    latency_ms: float = 0.0
    jitter_ms: float = 0.0
    drop: float = 0.0
    imu_noise: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("latency_ms", "jitter_ms", "imu_noise"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise SimError(f"{name} must be finite and >= 0; got {value}")
        if not (np.isfinite(self.drop) and 0 <= self.drop < 1):
            raise SimError(f"drop must be a probability in [0, 1); got {self.drop}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise SimError(f"seed must be an integer >= 0 (numpy's generators take no negative seed); "
                           f"got {self.seed!r}")

    @property
    def ideal(self) -> bool:
        """No delay, no drops, no noise."""
        return not (self.latency_ms or self.jitter_ms or self.drop or self.imu_noise)


class DelayLine(Generic[T]):
    """Messages in flight on one direction of a link (see the module docstring).

    Args:
        spec: The link.
        rng: Random source for the drops and jitter.
    """

    def __init__(self, spec: LinkSpec, rng: np.random.Generator):
        self.spec = spec
        self._rng = rng
        self._heap: list[tuple[float, int, T]] = []
        self._sent = 0
        self._newest_delivered = -1
        self.dropped = 0
        self.superseded = 0

    def send(self, now_s: float, message: T) -> None:
        """Put ``message`` on the link at time ``now_s`` [s]."""
        seq = self._sent
        self._sent += 1
        spec = self.spec
        if spec.drop and self._rng.random() < spec.drop:
            self.dropped += 1
            return
        delay_ms = spec.latency_ms + (self._rng.random() * spec.jitter_ms if spec.jitter_ms else 0.0)
        heapq.heappush(self._heap, (now_s + 1e-3 * delay_ms, seq, message))

    def receive(self, now_s: float) -> T | None:
        """The newest message arrived by ``now_s`` and newer than any delivered before, or None."""
        newest: tuple[int, T] | None = None
        heap = self._heap
        while heap and heap[0][0] <= now_s + 1e-12:
            _, seq, message = heapq.heappop(heap)
            if seq <= self._newest_delivered or (newest is not None and seq < newest[0]):
                self.superseded += 1
                continue
            if newest is not None:
                self.superseded += 1
            newest = (seq, message)
        if newest is None:
            return None
        self._newest_delivered = newest[0]
        return newest[1]


class LinkedSimulator:
    """The in-process simulator seen through a link: a :class:`RobotInterface` with delays and drops.

    The controller reads the newest state that has arrived and its commands reach the plant after
    the link's delay; until the first one arrives the plant is held still (``Simulator.hold``).
    With an ``estimator``, the state's base position and linear velocity are estimated from the
    (noisy) IMU and the joints, as over DDS.

    Args:
        sim: The plant (its control period is the interface's).
        spec: The link.
        estimator: Optional base-state estimator (needs ``imu``).
        imu: The IMU's site and sensors (with an estimator or IMU noise).

    Raises:
        SimError: An estimator or IMU noise without ``imu``.
    """

    def __init__(self, sim: Simulator, spec: LinkSpec, estimator: BaseStateEstimator | None = None,
                 imu: ImuSpec | None = None):
        if (estimator is not None or spec.imu_noise) and imu is None:
            raise SimError("an estimator or IMU noise needs the robot's IMU (imu=ImuSpec(...))")
        self.sim = sim
        self.spec = spec
        rng = np.random.default_rng(spec.seed)
        self._states: DelayLine[RobotState] = DelayLine(spec, rng)
        self._commands: DelayLine[Command] = DelayLine(spec, rng)
        self.estimator = estimator
        self._imu = ImuReader(sim, imu, spec.imu_noise, spec.seed + 1) if imu is not None else None
        self.started = False  # whether a command has reached the plant (before, it is held still)
        self.cycles = 0  # completed sync() calls
        self.commands_applied = 0  # commands the link delivered to the plant
        self.commanded_cycles = 0  # sync() calls during which at least one command reached the plant
        self._held_steps = 0
        if estimator is not None:
            estimator.reset(self._imu.proprioception(held=True))  # type: ignore[union-attr]
        self._latest = self._measure()
        self._states.send(sim.time_s, self._latest)
        self._latest = self._states.receive(sim.time_s) or self._latest

    def _measure(self) -> RobotState:
        if self.estimator is None:
            return self.sim.read_state()
        reading = self._imu.proprioception(held=not self.started)  # type: ignore[union-attr]
        q_base, v_base = self.estimator.update(reading)
        q = np.concatenate([q_base, reading.q_joints])
        v = np.concatenate([v_base, reading.v_joints])
        q.setflags(write=False)
        v.setflags(write=False)
        return RobotState(q, v, reading.time_s, self.estimator.estimated, self.sim.n_steps)

    @property
    def robot(self) -> Robot:
        """The model pair."""
        return self.sim.robot

    @property
    def control_period_s(self) -> float:
        """The simulator's control period [s]."""
        return self.sim.control_period_s

    @property
    def time_s(self) -> float:
        """Simulated time [s] (it runs while the plant is held before its first command)."""
        return self.sim.time_s

    @property
    def held_s(self) -> float:
        """How long [s] the plant was held still waiting for its first command (so far, while it waits)."""
        return self._held_steps * float(self.sim.model.opt.timestep)

    def read_state(self) -> RobotState:
        """The newest state the link has delivered (held while none arrives)."""
        return self._latest

    def send(self, command: Command) -> None:
        """Put ``command`` on the link; it reaches the plant after the link's delay (or never).

        Raises:
            CommandError, UnknownNameError: A command the plant would refuse (bound now, as every
                plant binds it, not when the link delivers it).
        """
        self.sim.binder.bind(command)
        self._commands.send(self.sim.time_s, command)

    def sync(self) -> None:
        """Advance the plant one control period, one physics step at a time (deliveries between steps).

        Before the first command has arrived the plant is held still for the step instead.
        """
        sim = self.sim
        applied = self.commands_applied
        for _ in range(sim.n_substeps):
            command = self._commands.receive(sim.time_s)
            if command is not None:
                sim.send(command)
                self.started = True
                self.commands_applied += 1
            if self.started:
                sim.step()
            else:
                sim.hold()
                self._held_steps += 1
            self._states.send(sim.time_s, self._measure())
        arrived = self._states.receive(sim.time_s)
        if arrived is not None:
            self._latest = arrived
        self.commanded_cycles += self.commands_applied > applied
        self.cycles += 1

    # ------------------------------------------------------------------ lifecycle and report
    def open(self) -> LinkedSimulator:
        """Nothing to connect (the plant is in-process); returns the interface."""
        return self

    def stop(self) -> None:
        """The loop is over: nothing to keep safe in simulation."""

    def close(self) -> None:
        """Nothing to leave safe in simulation (idempotent)."""

    def __enter__(self) -> LinkedSimulator:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def position_gains(self) -> dict[str, tuple[float, float]]:
        """The simulator's position actuators' (kp, kv), by joint name."""
        return self.sim.position_gains()

    def report(self) -> PlantReport:
        """The plant's report: simulated timing, the link's counts and model, the plant's clamp counts."""
        plant = self.sim.report()
        spec = self.spec
        link = LinkReport(
            "simulated", states_received=None, states_lost=self._states.dropped,
            commands_lost=self._commands.dropped, states_superseded=self._states.superseded,
            commands_superseded=self._commands.superseded, held_s=self.held_s,
            commands_applied=self.commands_applied, commanded_cycles=self.commanded_cycles,
            latency_ms=spec.latency_ms, jitter_ms=spec.jitter_ms, drop=spec.drop, imu_noise=spec.imu_noise)
        estimated = self.estimator.estimated if self.estimator is not None else ()
        return PlantReport("sim", replace(plant.timing, cycles=self.cycles), link, plant.safety, estimated)
