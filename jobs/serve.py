"""``mbctl serve g1``: the MuJoCo G1 as a robot on DDS, recording its ground truth.

The bridge (:mod:`mbctl.sim.dds_bridge`) runs paced to wall-clock time (``--lockstep``: one period
per command received, no faster than real time) until ``--duration`` (wall seconds),
``--idle-timeout`` seconds without a command (counted from its start until the first), or Ctrl-C
(status ``interrupted``, exit 130; every truth row written so far is kept). A plant that diverges
stops it (status ``diverged``, exit 1, naming the acceleration and how stale the last command was).
Its run folder holds ``truth.csv`` (base pose, CoM, feet, contact forces per physics step, with the
LowState tick),
``trajectory.npz`` + ``model.xml`` for ``mbctl replay``, and ``report.json`` with its counts (commands
received and applied, bad CRC, wrong mode, commands clamped to the robot's ranges and the clamps per
motor, link drops) and its own period statistics.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from mbctl.jobs.choices import SERVE_STARTS
from mbctl.jobs.runner import Job, JobError, Outcome, RunContext, Work
from mbctl.robots.g1 import KEYFRAME, crouched_start
from mbctl.robots.registry import load_robot
from mbctl.sim.dds_bridge import SERVING, TRUTH_COLUMNS, BridgeOptions, G1Bridge
from mbctl.sim.link import LinkSpec

#: Where the bridge's robot starts: the keyframe (g1-stand, g1-arm-pd) or g1-wbc's crouch.
STARTS = SERVE_STARTS
#: How often [cycles] the report's values are refreshed while serving.
_REFRESH = 500


class ServeError(JobError):
    """Bad ``mbctl serve`` options."""


@dataclass(frozen=True)
class ServeParams:
    """``mbctl serve g1`` (field names are the CLI options; see :class:`~mbctl.jobs.plant.PlantOptions`)."""

    robot: str = "g1"
    start: str = "stand"
    domain: int = 0
    network_interface: str = "lo"
    latency_ms: float = 0.0
    jitter_ms: float = 0.0
    drop: float = 0.0
    imu_noise: float = 0.0
    seed: int = 0
    duration: float | None = None
    idle_timeout: float | None = None
    model_dir: str | None = None
    lockstep: bool = False

    def __post_init__(self) -> None:
        if self.robot != "g1":
            raise ServeError(f"mbctl serve speaks the G1's low-level messages only; got robot {self.robot!r}")
        if self.start not in STARTS:
            raise ServeError(f"start must be one of {', '.join(STARTS)}; got {self.start!r}")
        for name in ("duration", "idle_timeout"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ServeError(f"{name} must be a positive number of seconds; got {value}")
        if self.lockstep and (self.latency_ms or self.jitter_ms or self.drop):
            raise ServeError("--lockstep advances one period per command: --latency-ms, --jitter-ms and "
                             "--drop need a wall clock; leave them out, or run without --lockstep")
        self.link  # noqa: B018 - validates the link numbers

    @property
    def link(self) -> LinkSpec:
        """The bridge's link model."""
        return LinkSpec(self.latency_ms, self.jitter_ms, self.drop, self.imu_noise, self.seed)


def prepare(params: ServeParams) -> Work:
    """Load the G1 and open DDS (errors here exit 2 before any output)."""
    robot = load_robot("g1", model_dir=params.model_dir)
    start_q = robot.keyframe_q(KEYFRAME) if params.start == "stand" else crouched_start(robot)
    bridge = G1Bridge(robot, start_q, BridgeOptions(params.domain, params.network_interface, params.link,
                                                    lockstep=params.lockstep))

    def work(ctx: RunContext) -> Outcome:
        ctx.attach(bridge.sim)
        # each row through at once: a client reads the log for its own last ticks as soon as it ends
        csv = ctx.open_csv(TRUTH_COLUMNS, "truth.csv", flush_interval_s=0.0)
        ctx.sections["inputs"] = {"start": params.start, "mode_machine": bridge.options.mode_machine,
                                  "robot_edits": list(bridge.robot.source.edits)}
        print(f"mbctl serve g1: {SERVING} {params.domain}, network interface "
              f"{params.network_interface!r}{', lock-step' if params.lockstep else ''} (Ctrl-C to stop)",
              file=sys.stderr, flush=True)

        def on_step(tick: int, wall_s: float) -> None:
            csv.write(bridge.truth_row(tick, wall_s))
            if tick % _REFRESH == 0:
                ctx.values.update(bridge.stats())

        try:
            reason = bridge.serve(params.duration, params.idle_timeout, on_step)
        finally:
            ctx.values.update(bridge.stats())
            bridge.close()
        v = ctx.values
        return Outcome(True, (
            f"serve g1: stopped ({reason}) after {v['cycles']} periods; {v['commands_applied']} commands "
            f"applied of {v['commands_received']} received ({v['bad_crc']} bad CRC, "
            f"{v['wrong_mode_machine']} wrong mode_machine, {v['commands_clamped']} clamped to the robot's "
            f"ranges{_per_motor(v['clamped_per_motor'])}); period p99 {v['period_p99_ms']:.2f} ms, "
            f"{v['deadline_misses']} deadline misses",))

    return work


def _per_motor(clamped: dict[str, int]) -> str:
    """`` (joint n, ...)`` of the motors clamped, or nothing."""
    return f" ({', '.join(f'{j} {n}' for j, n in clamped.items())})" if clamped else ""


#: ``mbctl serve g1``.
SERVE = Job("serve", prepare)
