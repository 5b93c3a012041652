"""What a plant reports about a run, typed and in one vocabulary whichever plant produced it.

Every :class:`~mbctl.robots.interface.RobotInterface` (the simulator, the simulator behind a link
model, a robot over DDS) answers ``report()`` with a :class:`PlantReport`: one frozen dataclass
per concern, with the same field names on every plant. A field a plant does not measure is
``None``, never a made-up zero (the in-process simulator has no wall-clock period, so its
``work_p99_ms`` is None; it loses no message, so ``states_lost`` is 0, measured).

Adding a figure (say, motor temperature) is one field here and one line in each plant that
measures it; the jobs read the report, never a plant's concrete type.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from types import MappingProxyType
from typing import Any


@dataclass(frozen=True)
class TimingReport:
    """The control loop's timing as the plant saw it.

    Attributes:
        cycles: Completed control cycles (``sync`` calls).
        period_p50_ms: Median time between cycle starts [ms] (simulated: the control period).
        period_p99_ms: Its 99th percentile [ms].
        period_max_ms: The longest [ms].
        deadline_misses: Cycles whose compute and IO overran the period (simulated: 0).
        work_p99_ms: 99th percentile of a cycle's compute and IO, wall clock [ms]; None in simulation.
        work_cpu_p99_ms: The same in the loop thread's CPU time [ms]; None in simulation.
        cpu_overruns: Cycles whose CPU time alone exceeded the period; None in simulation.
        stale_cycles: Cycles that found no new state and reused the last one.
        realtime: Whether the loop ran at real-time scheduling priority (DDS: where the OS permits
            it); None in simulation.
    """

    cycles: int
    period_p50_ms: float
    period_p99_ms: float
    period_max_ms: float
    deadline_misses: int = 0
    work_p99_ms: float | None = None
    work_cpu_p99_ms: float | None = None
    cpu_overruns: int | None = None
    stale_cycles: int = 0
    realtime: bool | None = None


@dataclass(frozen=True)
class LinkReport:
    """The link between the controller and the plant.

    Attributes:
        kind: "direct" (in-process, no link), "simulated" (the in-process link model) or "dds".
        states_received: States that reached the controller (None where every state does).
        states_lost: States sent but never received (dropped, or gaps in the robot's tick).
        commands_lost: Commands sent but never applied; None where the plant cannot tell (DDS).
        states_superseded: States that arrived after a newer one and were discarded.
        commands_superseded: Commands likewise; None where the plant cannot tell.
        bad_crc: States refused for a bad CRC (DDS; None elsewhere).
        bad_encoding: States refused for another encoding (DDS; None elsewhere).
        held_s: How long [s] the plant was held still before its first command arrived.
        commands_applied: Commands that reached the plant (None where the plant cannot tell: DDS,
            whose client does not see the robot apply them).
        commanded_cycles: Control cycles during which at least one command reached the plant
            (None where the plant cannot tell).
        latency_ms: The simulated link's delay each direction [ms] (None unless simulated).
        jitter_ms: Its extra uniform delay [ms] (None unless simulated).
        drop: Its probability of losing a message (None unless simulated).
        imu_noise: IMU noise as a multiple of the model's declared noise (None unless simulated).
        domain: DDS domain id (None unless DDS).
        network_interface: The network interface (None unless DDS).
        mode_machine: The robot's ``mode_machine`` (None unless DDS).
        state_order: How newer states are told from older ones (DDS): "tick" (the robot's tick
            advances: an older or repeated tick is superseded) or "arrival" (the tick does not
            advance, as in Unitree's simulator: the latest to arrive is the newest).
        state_rate_hz: The state rate the loop is paced by [Hz] (DDS: measured at connect or given).
        bad_states: States refused for their values (DDS: a non-finite or non-unit IMU quaternion,
            non-finite joints or IMU, a tick far ahead of the last).
        crc_unchecked: States accepted with CRC 0, unchecked (DDS, only when asked to).
        state_gap_p99_ms: 99th percentile of the waits between new states during the loop [ms]
            (DDS: what the watchdog is compared with).
        state_gap_max_ms: The longest of them [ms].
    """

    kind: str
    states_received: int | None = None
    states_lost: int = 0
    commands_lost: int | None = 0
    states_superseded: int = 0
    commands_superseded: int | None = 0
    bad_crc: int | None = None
    bad_encoding: int | None = None
    held_s: float = 0.0
    commands_applied: int | None = None
    commanded_cycles: int | None = None
    latency_ms: float | None = None
    jitter_ms: float | None = None
    drop: float | None = None
    imu_noise: float | None = None
    domain: int | None = None
    network_interface: str | None = None
    mode_machine: int | None = None
    state_order: str | None = None
    state_rate_hz: float | None = None
    bad_states: int | None = None
    crc_unchecked: int | None = None
    state_gap_p99_ms: float | None = None
    state_gap_max_ms: float | None = None


@dataclass(frozen=True)
class SafetyReport:
    """What the plant did to keep the robot safe.

    Attributes:
        clamped: Values clamped to their limits, per actuator name (non-zero only); read-only.
        clamped_commands: Commands in which at least one value was clamped.
        watchdog_events: Times the link was declared lost.
        damped: Whether the damping command was sent at the end; None for a plant without one
            (the simulator: nothing to protect).
        gains_lowered: Motor gains the plant lowered to keep its motor law stable, per joint:
            gain name (``kp``, ``kd``, ``damping_kd``) -> (given, sent); read-only.
    """

    clamped: Mapping[str, int] = field(default_factory=dict)
    clamped_commands: int = 0
    watchdog_events: int = 0
    damped: bool | None = None
    gains_lowered: Mapping[str, Mapping[str, tuple[float, float]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "clamped", MappingProxyType(dict(self.clamped)))
        object.__setattr__(self, "gains_lowered", MappingProxyType(
            {j: MappingProxyType(dict(g)) for j, g in self.gains_lowered.items()}))


@dataclass(frozen=True)
class PlantReport:
    """A plant's report on a run: which interface, and its timing, link and safety figures.

    Attributes:
        interface: "sim" (in-process, with or without a link model) or "dds".
        timing: The loop's timing.
        link: The link's counts.
        safety: Clamping, watchdog, damping.
        estimated: The state fields estimated rather than measured (e.g. ``base_position``).
    """

    interface: str
    timing: TimingReport
    link: LinkReport
    safety: SafetyReport
    estimated: tuple[str, ...] = ()

    def values(self) -> dict[str, Any]:
        """The report as flat key -> value for ``report.json`` (the keys the jobs have always written).

        Timing and link fields keep their names; ``messages_lost`` is ``link.states_lost`` and
        ``clamped`` the per-actuator counts. Fields that were not measured (None) are left out.
        """
        flat: dict[str, Any] = {"interface": self.interface}
        for part in (self.timing, self.link):
            flat.update({k: v for k, v in asdict(part).items() if v is not None and k != "kind"})
        flat["link"] = self.link.kind
        flat["messages_lost"] = self.link.states_lost
        flat["clamped"] = dict(self.safety.clamped)
        flat["clamped_commands"] = self.safety.clamped_commands
        flat["watchdog_events"] = self.safety.watchdog_events
        if self.safety.damped is not None:
            flat["damped"] = self.safety.damped
        if self.safety.gains_lowered:
            flat["gains_lowered"] = {j: {k: list(v) for k, v in g.items()}
                                     for j, g in self.safety.gains_lowered.items()}
        return flat
