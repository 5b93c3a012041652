"""Which plant a G1 job runs on: the in-process simulator (optionally through a link) or the G1 over DDS.

The jobs build their controller as before and take a :class:`RobotInterface` from here, so the
same controller object runs on either plant through ``control.loop.run``:

- ``--interface sim`` (default): the :class:`Simulator`, reset to the job's start; with any of
  ``--latency-ms``, ``--jitter-ms``, ``--drop``, ``--imu-noise`` or ``--estimate`` it is seen
  through :class:`LinkedSimulator` (the bridge's link model, at simulation speed, sweepable).
- ``--interface dds``: :class:`~mbctl.hardware.UnitreeG1` on ``--domain`` and
  ``--network-interface`` (default ``lo``: ``mbctl serve g1`` on this machine; ``--dds-config``
  a Cyclone configuration of the user's for anything else), with the leg-kinematics estimator for
  the base. It connects in the job's ``prepare`` (waiting up to ``--wait-s`` for the robot, said on
  stderr when longer than the default), so no robot or a joint outside its limits is bad input
  (exit 2) before any file is written. The state rate is measured at connect (``--rate-hz`` gives
  it); states with CRC 0 are refused unless ``--state-crc off`` (Unitree's simulator). The link's
  imperfections are the bridge's (``mbctl serve g1 --latency-ms ...``).

However a job's loop ends, the plant keeps the robot safe until the job is done (``stop()``:
``control.loop.run`` calls it; over DDS the damping command every period); the report gets the
plant's figures even when the loop failed (:meth:`Plant.__exit__`).

:func:`report_plant` adds the report values every plant gives (``interface``, ``cycles``, the
period percentiles, ``deadline_misses``, ``messages_lost``, ``watchdog_events``) and, with the
bridge's truth log (``--truth``), the plant checks of :mod:`mbctl.jobs.truth`; and it refuses a
pass to a run whose commands did not reach the plant in at least :data:`MIN_COMMANDED_FRACTION`
of its cycles (:func:`check_commanded`).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.estimation import LegKinematicsEstimator
from mbctl.control.loop import RunLog
from mbctl.control.wbc.contacts import foot_contact_from_model
from mbctl.hardware import DdsOptions, UnitreeG1
from mbctl.hardware.dds_options import CONNECT_TIMEOUT_S, WATCHDOG_PERIODS
from mbctl.jobs.model_options import ModelOptions
from mbctl.jobs.recording import q_columns
from mbctl.jobs.runner import JobError, Outcome, RunContext
from mbctl.jobs.truth import check_truth_header, truth_checks
from mbctl.limits import check_limit
from mbctl.robots.g1 import FEET, G1_IMU
from mbctl.robots.interface import RobotInterface
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_report import PlantReport
from mbctl.sim.link import LinkedSimulator, LinkSpec
from mbctl.sim.simulator import Simulator
from mbctl.unitree.channel import LOOPBACK, check_domain

INTERFACES = ("sim", "dds")
#: A run is judged only if a command reached the plant in at least this fraction of its control
#: cycles. Below it the plant ran (or was held still) mostly without its controller: a link
#: latency longer than the run, or nearly every command dropped, says nothing of the controller,
#: however well the robot "stood" (the run's status is then ``uncommanded``, exit 1).
MIN_COMMANDED_FRACTION = 0.5
#: The longest run on a plant [s] (``--duration``): an hour. The CSV streams every cycle to disk, the
#: trajectory kept for replay is bounded (``mbctl.sim.recorder.MAX_REPLAY_SAMPLES``), and so is the
#: control loop's log (``control.loop.MAX_LOG_ROWS`` rows; its times, ticks and sums every cycle, 16
#: bytes a cycle, so the figures stay exact): g1-stand peaked at 0.98 GB for 20 s, 0.99 GB for 600 s
#: and 1.05 GB for 3600 s (``/usr/bin/time``'s max RSS). (``mbctl.limits.MAX_DURATION_S``, 600 s,
#: still caps the in-process-only jobs.)
MAX_RUN_S = 3600.0
#: ``--state-crc``: check the CRC of every state (on), or accept states with CRC 0 unchecked (off).
STATE_CRC = ("on", "off")
#: ``--motor-gains``: lower the gains a motor law applied once per state period would not keep stable
#: (stable; ``mbctl.hardware.motor_law``), or send the model's as they are (as-given).
MOTOR_GAINS = ("stable", "as-given")
#: The G1 estimator's flat-ground measurement [m] (``LegKinematicsEstimator(ground_noise_m=)``): each
#: foot in contact at the start's ground height, within this. The walker assumes that ground too
#: (its touchdowns from the sole's height over DDS). Without it the height was carried from foot to
#: foot: g1-walk forward 0.3 m/s, 20 s, on Unitree's simulator (flat) estimated it 3 mm high, its
#: touchdowns late (a sole's centre 3 mm above the ground) and the heading swung up to 0.24-0.32
#: rad; in-process with --estimate it rose 63 mm (0.58 rad). With it: 1.2 mm, 0.016 rad; 2.8 mm,
#: 0.019 rad.
GROUND_NOISE_M = 0.002


class PlantOptionError(JobError):
    """Plant options that do not go together (e.g. a link model on a DDS run)."""


@dataclass(frozen=True)
class PlantOptions:
    """The plant options of the G1 jobs (field names are the CLI options).

    Attributes:
        interface: "sim" (in-process) or "dds" (the G1's low-level DDS).
        domain: DDS domain id (dds).
        network_interface: The interface wired to the robot (dds; default ``lo``).
        latency_ms: Link delay each direction [ms] (sim).
        jitter_ms: Extra uniform delay [ms] (sim).
        drop: Probability of losing a message, each direction (sim).
        imu_noise: IMU noise as a multiple of the model's declared sensor noise (sim).
        estimate: Base position and velocity from the estimator instead of the plant (sim; always
            over DDS).
        seed: Seed of the link's randomness (sim).
        truth: The bridge's truth log (``truth.csv`` of ``mbctl serve g1``) for the plant checks (dds).
        watchdog_periods: Periods without a state before the link counts as lost (dds).
        dry_run: Read and report the robot's state, never command (dds).
        state_crc: "on" (the real G1 signs its states) or "off": states with CRC 0 accepted
            unchecked (Unitree's simulator leaves it 0) (dds).
        rate_hz: The robot's state rate [Hz]; None measures it at connect (dds).
        wait_s: How long to wait for the robot's state stream [s] (dds).
        dds_config: A Cyclone DDS configuration file of the user's, used as written (dds).
        motor_gains: "stable" (the gains checked against the state period, lowered where a motor
            law applied once per period would not keep them stable) or "as-given" (dds).
    """

    interface: str = "sim"
    domain: int = 0
    network_interface: str = LOOPBACK
    latency_ms: float = 0.0
    jitter_ms: float = 0.0
    drop: float = 0.0
    imu_noise: float = 0.0
    estimate: bool = False
    seed: int = 0
    truth: str | None = None
    watchdog_periods: int = WATCHDOG_PERIODS
    dry_run: bool = False
    state_crc: str = "on"
    rate_hz: float | None = None
    wait_s: float = CONNECT_TIMEOUT_S
    dds_config: str | None = None
    motor_gains: str = "stable"

    def __post_init__(self) -> None:  # noqa: C901 - one check per option, each with its message
        if self.interface not in INTERFACES:
            raise PlantOptionError(f"interface must be one of {', '.join(INTERFACES)}; "
                                   f"got {self.interface!r}")
        spec = self.link  # validates the numbers
        if self.interface == "dds":
            check_domain(self.domain)
            if not spec.ideal or self.seed:
                raise PlantOptionError(
                    "over DDS the link is the real one (or the bridge's): give --latency-ms, --jitter-ms, "
                    "--drop and --imu-noise to `mbctl serve g1`, not to the client")
            if self.watchdog_periods < 1:
                raise PlantOptionError(f"watchdog_periods must be >= 1; got {self.watchdog_periods}")
            if self.state_crc not in STATE_CRC:
                raise PlantOptionError(f"state_crc must be one of {', '.join(STATE_CRC)}; "
                                       f"got {self.state_crc!r}")
            if self.motor_gains not in MOTOR_GAINS:
                raise PlantOptionError(f"motor_gains must be one of {', '.join(MOTOR_GAINS)}; "
                                       f"got {self.motor_gains!r}")
            if self.rate_hz is not None and not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
                raise PlantOptionError(f"rate_hz must be a positive number of Hz (the G1's is 500); "
                                       f"got {self.rate_hz}")
            if not (np.isfinite(self.wait_s) and self.wait_s > 0):
                raise PlantOptionError(f"wait_s must be a positive number of seconds; got {self.wait_s}")
        else:
            self._refuse_dds_options()

    def _refuse_dds_options(self) -> None:
        """In-process, a DDS option would be silently ignored (a forgotten ``--interface dds``): refuse it.

        An option counts as given when it differs from its default.
        """
        given = [name for name, default, value in (
            ("--domain", 0, self.domain), ("--network-interface", LOOPBACK, self.network_interface),
            ("--watchdog-periods", WATCHDOG_PERIODS, self.watchdog_periods), ("--truth", None, self.truth),
            ("--dry-run", False, self.dry_run), ("--state-crc", "on", self.state_crc),
            ("--rate-hz", None, self.rate_hz), ("--wait-s", CONNECT_TIMEOUT_S, self.wait_s),
            ("--dds-config", None, self.dds_config), ("--motor-gains", "stable", self.motor_gains))
            if value != default]
        if given:
            one = len(given) == 1
            raise PlantOptionError(
                f"{', '.join(given)} {'is an option' if one else 'are options'} of --interface dds; this "
                f"run is in-process (--interface sim), where {'it' if one else 'they'} would be ignored (the "
                f"in-process plant is the truth, always commanded, with no state stream): add --interface "
                f"dds to run on the robot or `mbctl serve g1`, or leave {'it' if one else 'them'} out")

    def check_duration(self, duration_s: float | None) -> None:
        """Refuse a run too long for memory, or one its own link would leave uncommanded throughout.

        Args:
            duration_s: The run's duration [s] (None: the job's own, checked where it is known).

        Raises:
            SizeLimitError: Over :data:`MAX_RUN_S`.
            PlantOptionError: A link latency at least the duration (no command would reach the plant).
        """
        if duration_s is None:
            return
        check_limit("--duration", duration_s, MAX_RUN_S, " s", "a run over an hour is a CSV of over "
                    "1.8 million rows (the G1 at 500 Hz: about 2 GB); run shorter pieces")
        if self.latency_ms * 1e-3 >= duration_s:
            raise PlantOptionError(
                f"--latency-ms {self.latency_ms:g} is not shorter than the run ({duration_s:g} s): no "
                f"command would reach the plant before the run ends; give a latency below "
                f"{duration_s * 1e3:g} ms")

    def check_models(self, models: ModelOptions) -> None:
        """Refuse a hidden plant change over DDS: there the plant is the robot (or the bridge's model).

        Raises:
            PlantOptionError: ``--payload`` or ``--plant-error`` with ``--interface dds``.
        """
        if self.interface == "dds" and models.hidden:
            raise PlantOptionError("--payload and --plant-error change the in-process plant; over "
                                   "--interface dds the plant is the robot (or `mbctl serve g1`'s "
                                   "model). --controller-model works on both")

    @property
    def link(self) -> LinkSpec:
        """The in-process link model."""
        return LinkSpec(self.latency_ms, self.jitter_ms, self.drop, self.imu_noise, self.seed)


def g1_estimator(robot: Robot, start_xy_m: tuple[float, float] = (0.0, 0.0)) -> LegKinematicsEstimator:
    """The leg-kinematics estimator on the G1's feet (contact point: the sole's centre) and pelvis IMU.

    On flat ground: the feet in contact at the start's ground height (:data:`GROUND_NOISE_M`).
    """
    feet = {f: foot_contact_from_model(robot, f).points_F.mean(axis=0) for f in FEET}
    return LegKinematicsEstimator(robot, feet, G1_IMU.site, start_xy_m=start_xy_m,
                                  ground_noise_m=GROUND_NOISE_M)


@dataclass
class Plant:
    """What a job's work runs on.

    Attributes:
        interface: The robot API the control loop drives.
        sim: The in-process plant (None over DDS).
        options: The plant options.
        estimator: The base-state estimator behind the plant's states (over DDS, or in-process with
            ``--estimate``), which a job that lifts a foot tells the feet on the ground; else None.
    """

    interface: RobotInterface
    sim: Simulator | None
    options: PlantOptions
    ctx: RunContext | None = None
    estimator: LegKinematicsEstimator | None = None

    def close(self) -> None:
        """Leave the robot in a safe state (DDS: damping) and close the connection (the plant contract)."""
        self.interface.close()

    def __enter__(self) -> Plant:
        return self

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        """Close; a job that failed or was interrupted still reports the plant's figures (the link's)."""
        try:
            if kind is not None and self.ctx is not None:
                self.interface.stop()  # the loop may have failed before it ran: keep the robot safe
                values = self.interface.report().values()
                self.ctx.values.update({k: v for k, v in values.items() if k not in self.ctx.values})
        finally:
            self.close()


PlantFactory = Callable[[RunContext], Plant]


def prepare_plant(options: PlantOptions, robot: Robot, keyframe: str | None = None,
                  start_q: np.ndarray | None = None, contact_forces: bool = False) -> PlantFactory:
    """Check the options and, over DDS, connect (no robot: exit 2 before any output).

    Args:
        options: The plant options.
        robot: The robot the controller is built for.
        keyframe: The in-process start (its ctrl too), or None.
        start_q: The in-process start configuration (nq,) (after the keyframe), or None.
        contact_forces: A filmed in-process run draws the contact forces.

    Returns:
        A function of the run's context that gives the plant (the simulator is attached to the run).

    Raises:
        NoRobotError, JointOutOfLimits, ChannelError: Over DDS, before anything is written.
    """
    if options.interface == "dds":
        # a file that is no truth log: exit 2 before connecting; one not there yet is the log of a
        # bridge still loading (the README's `serve ... &` then the client): checked once it serves
        truth_later = options.truth is not None and not Path(options.truth).exists()
        if options.truth is not None and not truth_later:
            check_truth_header(options.truth)
        if options.wait_s > CONNECT_TIMEOUT_S:
            print(f"mbctl: waiting up to {options.wait_s:g} s for the robot's state on DDS domain "
                  f"{options.domain}, network interface {options.network_interface!r} (--wait-s)",
                  file=sys.stderr, flush=True)
        legs = g1_estimator(robot)
        dds = UnitreeG1(robot, legs, DdsOptions(
            domain=options.domain, network_interface=options.network_interface, rate_hz=options.rate_hz,
            connect_timeout_s=options.wait_s, watchdog_periods=options.watchdog_periods,
            dry_run=options.dry_run, check_state_crc=options.state_crc == "on",
            cyclone_config=options.dds_config, stable_gains=options.motor_gains == "stable"), feet=FEET)
        if truth_later:
            try:
                check_truth_header(options.truth)  # type: ignore[arg-type]
            except BaseException:
                dds.close()  # never commanded: nothing to damp
                raise
        return lambda ctx: Plant(dds, None, options, ctx, legs)

    def make(ctx: RunContext) -> Plant:
        sim = Simulator(robot)
        sim.reset(keyframe)
        if start_q is not None:
            sim.set_state(start_q, np.zeros(robot.nv))
        ctx.attach(sim, contact_forces=contact_forces)
        if options.link.ideal and not options.estimate:
            return Plant(sim, sim, options)
        q = sim.read_state().q
        estimator = g1_estimator(robot, (float(q[0]), float(q[1]))) if options.estimate else None
        return Plant(LinkedSimulator(sim, options.link, estimator, G1_IMU), sim, options, estimator=estimator)

    return make


def report_plant(ctx: RunContext, plant: Plant, log: RunLog,
                 fall_height_m: float | None = None) -> bool | None:
    """Add the plant's report values; with a truth log, check the run against it.

    Every job on the plant comes through here, so each gets :func:`check_commanded`: a run whose
    controller never acted on the plant (a latency longer than the run, every command dropped) is
    ``uncommanded``, not a pass.

    Args:
        ctx: The run.
        plant: The plant the run used.
        log: The control loop's log.
        fall_height_m: Pelvis height [m] below which the robot has fallen, in the truth check.

    Returns:
        Whether the robot fell according to the truth log, or None without one.
    """
    report = plant.interface.report()
    values = report.values()
    values["cycles"] = log.cycles  # the loop's own count (the plant's may include cycles outside it)
    ctx.values.update(values)
    if "base_position" in report.estimated:
        ctx.sections["estimator"] = {"kind": "leg kinematics Kalman filter", "feet": list(FEET),
                                     "imu": G1_IMU.site, "estimated": list(report.estimated)}
    truth_fell = None
    if plant.options.truth is not None:
        now = time.time()  # the loop ended moments ago: its wall-clock span, for the log's identity
        checks = truth_checks(plant.options.truth, log.tick, log, fall_height_m, (now - log.wall_time_s, now))
        ctx.values.update(checks)
        truth_fell = bool(checks["truth_fell"])
    check_commanded(ctx, report, log.cycles)
    return truth_fell


def check_commanded(ctx: RunContext, report: PlantReport, cycles: int) -> bool | None:
    """Whether the controller acted on the plant in enough of the run's cycles to judge it.

    Adds ``commanded_cycles``, ``commanded_fraction`` and ``controller_acted`` to the run's values
    (None where the plant cannot tell: over DDS without the bridge's truth log). Below
    :data:`MIN_COMMANDED_FRACTION` the run is not a pass (:meth:`RunContext.refuse_pass`).

    Args:
        ctx: The run.
        report: The plant's report.
        cycles: Control cycles the loop ran.

    Returns:
        Whether it acted enough, or None when not known.
    """
    link = report.link
    commanded: int | None = link.commanded_cycles
    if link.kind == "direct":  # the simulator applies each command when it is sent
        commanded = cycles
    elif commanded is None and "truth_commands_applied" in ctx.values:  # the bridge's count, over DDS
        commanded = min(cycles, int(ctx.values["truth_commands_applied"]))
    fraction = commanded / cycles if commanded is not None and cycles else None
    acted = None if fraction is None else bool(fraction >= MIN_COMMANDED_FRACTION)
    ctx.values.update({"commanded_cycles": commanded, "commanded_fraction": fraction,
                       "controller_acted": acted})
    if acted is False:
        ctx.refuse_pass(_uncommanded_reason(report, commanded or 0, cycles))
    return acted


def _uncommanded_reason(report: PlantReport, commanded: int, cycles: int) -> str:
    """Why a run's controller did not act (see :func:`check_commanded`), with the link's figures."""
    link = report.link
    why = []
    if link.held_s:
        why.append(f"the plant was held still {link.held_s:.3f} s waiting for its first command"
                   + (f" (--latency-ms {link.latency_ms:g})" if link.latency_ms else ""))
    if link.commands_lost:
        why.append(f"{link.commands_lost} commands lost" + (f" (--drop {link.drop:g})" if link.drop else ""))
    head = ("the controller never acted: no command reached the plant in any" if commanded == 0 else
            f"the controller acted in too few cycles to judge it: a command reached the plant in {commanded}")
    return (f"{head} of the run's {cycles} control cycles (at least {MIN_COMMANDED_FRACTION:.0%} are "
            "needed)" + (f"; {'; '.join(why)}" if why else "") + ": the run's figures are the plant's alone")


def plant_lines(v: dict[str, Any]) -> tuple[str, ...]:
    """The summary lines of a run through a link or over DDS (none in-process)."""
    if v.get("interface") != "dds":
        return ()
    lines: tuple[str, ...] = (f"dds: {v['cycles']} cycles, period p50 {v['period_p50_ms']:.3f} ms, p99 "
             f"{v['period_p99_ms']:.3f} ms, {v['deadline_misses']} deadline misses (compute and IO p99 "
             f"{v['work_p99_ms']:.2f} ms, {v['work_cpu_p99_ms']:.2f} ms of it on the CPU; "
             f"{v['cpu_overruns']} cycles over the period on the CPU), {v['messages_lost']} messages lost, "
             f"{v['watchdog_events']} watchdog events",)
    if "truth_pelvis_max_deviation_m" in v:
        estimator = (f"estimator error max {v['estimator_position_error_max_m'] * 1e3:.2f} mm, "
                     f"{v['estimator_orientation_error_max_deg']:.3f} deg"
                     if v.get("estimator_position_error_max_m") is not None else
                     f"estimator error max {v.get('estimator_errors_over')}")
        lines += (f"truth: pelvis max deviation {v['truth_pelvis_max_deviation_m'] * 1e3:.2f} mm, foot slip "
                  f"{v['truth_max_foot_slip_m'] * 1e3:.3f} mm; {estimator}",)
    return lines


def dry_run(ctx: RunContext, plant: Plant, duration_s: float) -> Outcome:
    """Read the robot's state for ``duration_s`` at the control period, never commanding; report it.

    Writes every state to the run's CSV and returns a summary of the last one: base orientation
    (IMU), estimated base position, and each joint's angle with its distance to its limits.
    """
    iface = plant.interface
    robot = iface.robot
    header = ["time_s", *q_columns(robot)]
    csv = ctx.open_csv(header)
    n = max(1, int(round(duration_s / iface.control_period_s)))
    ctx.progress.start(n, "dry run (reading only)")
    state = iface.read_state()
    for _ in range(n):
        state = iface.read_state()
        csv.write([state.time_s, *state.q])
        ctx.progress.advance()
        iface.sync()
    ctx.values.update({**iface.report().values(), "dry_run": True, "cycles": n})
    q = state.q
    roll, pitch, yaw = np.degrees(pin.rpy.matrixToRpy(pin.Quaternion(q[6], q[3], q[4], q[5]).matrix()))
    lines = [f"dry run: read {n} states over {duration_s:g} s, sent no command",
             f"base: roll {roll:.2f} deg, pitch {pitch:.2f} deg, yaw {yaw:.2f} deg (IMU); position "
             f"{q[0]:.4f}, {q[1]:.4f}, {q[2]:.4f} m ({', '.join(state.estimated) or 'measured'} estimated)"]
    low, high = robot.pin_model.lowerPositionLimit, robot.pin_model.upperPositionLimit
    for name, j in robot.joints.items():
        if j.kind in ("hinge", "slide"):
            i = j.idx_q
            lines.append(f"  {name:28s} {q[i]:+.4f} rad  (limits {low[i]:+.3f} .. {high[i]:+.3f})")
    return Outcome(True, tuple(lines))
