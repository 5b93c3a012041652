"""The joint-step job: raise one joint's position target and watch the plant respond."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mbctl.robots.commands import position_target
from mbctl.robots.exceptions import CommandError
from mbctl.robots.model_pair import Robot
from mbctl.sim.atomic import write_json_atomic
from mbctl.sim.recorder import (
    Recorder,
    base_z_column,
    joint_columns,
    sensor_columns,
    target_columns,
    time_column,
)
from mbctl.sim.report import execution_report
from mbctl.sim.simulator import Simulator


@dataclass(frozen=True)
class JointStepResult:
    """Outcome of a joint step.

    Attributes:
        joint: Joint name.
        before_rad: Joint angle before the step [rad].
        target_rad: Commanded target [rad].
        final_rad: Joint angle after the last step [rad].
        base_z_before_m: Base height at the start [m] (NaN for a fixed base).
        base_z_final_m: Base height at the end [m] (NaN for a fixed base).
        steps: Physics steps taken.
        simulated_time_s: Simulated time [s].
        warnings: MuJoCo warning counters.
        csv_path: Recording.
        report_path: JSON report.
    """

    joint: str
    before_rad: float
    target_rad: float
    final_rad: float
    base_z_before_m: float
    base_z_final_m: float
    steps: int
    simulated_time_s: float
    warnings: dict[str, int]
    csv_path: Path
    report_path: Path

    def summary(self) -> str:
        """A human-readable summary with units."""
        lines = [
            f"joint {self.joint}: before {self.before_rad:+.5f} rad, target {self.target_rad:+.5f} rad, "
            f"final {self.final_rad:+.5f} rad (error {self.final_rad - self.target_rad:+.2e} rad)",
            f"steps {self.steps}, simulated time {self.simulated_time_s:.3f} s",
        ]
        if np.isfinite(self.base_z_final_m):
            lines.append(
                f"base height: before {self.base_z_before_m:.4f} m, final {self.base_z_final_m:.4f} m"
            )
        lines.append(f"MuJoCo warnings: {self.warnings or 'none'}")
        lines.append(f"wrote {self.csv_path} and {self.report_path}")
        return "\n".join(lines)


def joint_step(
    robot: Robot,
    joint: str,
    delta_rad: float,
    steps: int,
    output_dir: str | os.PathLike,
    *,
    keyframe: str | None = None,
    sensors: tuple[str, ...] = (),
) -> JointStepResult:
    """Reset (to ``keyframe``), raise ``joint``'s position target by ``delta_rad``, step, record.

    Other position actuators hold the keyframe's ctrl (or, without a keyframe, the current joint
    angles). Every step is one CSV row; the JSON report carries before/target/final values.

    Raises:
        UnknownNameError: Unknown joint, keyframe or sensor.
        CommandError: The joint has no position actuator, or a non-position actuator exists
            among those the full target vector would drive.
    """
    if steps < 1:
        raise CommandError(f"steps must be >= 1; got {steps}")
    if not np.isfinite(delta_rad):
        raise CommandError(f"delta must be finite; got {delta_rad}")
    info = robot.actuator_for_joint(joint)
    if info.kind != "position":
        raise CommandError(
            f"joint {joint!r} is driven by {info.name!r}, a {info.kind} actuator; joint-step needs a "
            "position actuator (use a position-actuated model)"
        )
    for name in sensors:
        robot.sensor(name)
    sim = Simulator(robot)
    sim.reset(keyframe)
    q0 = sim.q
    position_actuators = [a for a in robot.actuators.values() if a.kind == "position"]
    if keyframe is not None:
        base_targets = {a.name: float(robot.keyframe_ctrl(keyframe)[a.index]) for a in position_actuators}
    else:
        base_targets = {a.name: float(q0[robot.joint(a.joint).idx_q]) for a in position_actuators}
    targets = dict(base_targets)
    targets[info.name] += delta_rad
    command = position_target(targets)
    idx_q = robot.joint(joint).idx_q
    before = float(q0[idx_q])
    z0 = sim.base_z_m
    out = Path(output_dir)
    columns = [time_column(), *joint_columns(sim, [joint]), *target_columns(sim, [info.name])]
    if robot.has_floating_base:
        columns.append(base_z_column())
    columns += sensor_columns(sim, sensors)
    with Recorder(out / "joint_step.csv", columns) as rec:
        sim.send(command)
        rec.record(sim)
        for _ in range(steps):
            sim.step()
            rec.record(sim)
    sim.forward()
    final = float(sim.q[idx_q])
    report = execution_report(
        sim,
        "joint-step",
        inputs={"joint": joint, "actuator": info.name, "delta_rad": delta_rad, "steps": steps,
                "keyframe": keyframe, "sensors": list(sensors)},
        values={"before_rad": before, "target_rad": targets[info.name], "final_rad": final,
                "error_rad": final - targets[info.name], "base_z_before_m": z0,
                "base_z_final_m": sim.base_z_m},
        outputs={"csv": str(rec.path), "csv_rows": rec.rows},
    )
    report_path = write_json_atomic(out / "joint_step_report.json", report)
    return JointStepResult(joint, before, targets[info.name], final, z0, sim.base_z_m, sim.n_steps,
                           sim.time_s, sim.warnings, rec.path, report_path)
