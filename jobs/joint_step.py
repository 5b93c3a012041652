"""The joint-step job: raise one joint's position target and watch the plant respond."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mbctl.jobs.model_options import ModelOptions, build_models, models_line
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.limits import MAX_STEPS, check_limit
from mbctl.robots.commands import position_target
from mbctl.robots.exceptions import CommandError
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.recorder import (
    Recorder,
    base_z_column,
    joint_columns,
    sensor_columns,
    target_columns,
    time_column,
)
from mbctl.sim.simulator import Simulator


@dataclass(frozen=True)
class JointStepParams:
    """What ``mbctl joint-step`` runs.

    Attributes:
        robot: Known robot name or MJCF robot file.
        joint: Joint whose position target is raised.
        delta_rad: Target increase [rad] (or [m] for a slide joint).
        steps: Physics steps to take (>= 1).
        keyframe: Keyframe to reset to, or None (hold the current joint angles).
        sensors: Sensors to record, every channel.
        scene: Scene MJCF for MuJoCo when ``robot`` is a path.
        model_dir: Explicit Menagerie model directory for a known robot (the G1).
        plant: Hidden plant changes (payload, mass error); a controller model is checked but unused
            (the position actuators are MuJoCo's own PD: no model).
    """

    robot: str
    joint: str
    delta_rad: float
    steps: int = 250
    keyframe: str | None = None
    sensors: tuple[str, ...] = ()
    scene: str | None = None
    model_dir: str | None = None
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise CommandError(f"steps must be >= 1; got {self.steps}")
        check_limit("--steps", self.steps, MAX_STEPS, advice="every step is a CSV row; take fewer")
        if not np.isfinite(self.delta_rad):
            raise CommandError(f"delta must be finite; got {self.delta_rad}")


def prepare(params: JointStepParams, robot: Robot | None = None) -> Work:
    """Load and check every name (joint, its position actuator, keyframe, sensors); no output yet.

    Other position actuators hold the keyframe's ctrl (or, without a keyframe, the current joint
    angles). Every step is one CSV row; the report carries before/target/final values.

    Raises:
        UnknownNameError: Unknown joint, keyframe or sensor.
        CommandError: The joint has no position actuator.
    """
    models = build_models(robot or load_robot(params.robot, params.scene, model_dir=params.model_dir),
                          params.models)
    robot = models.plant
    joint, keyframe, sensors = params.joint, params.keyframe, params.sensors
    info = robot.actuator_for_joint(joint)
    if info.kind != "position":
        raise CommandError(
            f"joint {joint!r} is driven by {info.name!r}, a {info.kind} actuator; joint-step needs a "
            "position actuator (use a position-actuated model)"
        )
    for name in sensors:
        robot.sensor(name)
    if keyframe is not None:
        robot.keyframe_q(keyframe)

    def work(ctx: RunContext) -> Outcome:
        sim = ctx.attach(Simulator(robot))
        ctx.sections["plant"] = {**models.section(), "controller_model_used": False}
        sim.reset(keyframe)
        q0 = sim.q
        position_actuators = [a for a in robot.actuators.values() if a.kind == "position"]
        if keyframe is not None:
            ctrl = robot.keyframe_ctrl(keyframe)
            base_targets = {a.name: float(ctrl[a.index]) for a in position_actuators}
        else:
            base_targets = {a.name: float(q0[robot.joint(a.joint).idx_q]) for a in position_actuators}
        targets = dict(base_targets)
        targets[info.name] += params.delta_rad
        command = position_target(targets)
        idx_q = robot.joint(joint).idx_q
        before = float(q0[idx_q])
        z0 = sim.base_z_m
        ctx.values.update({"joint": joint, "actuator": info.name, "before_rad": before,
                           "target_rad": targets[info.name], "base_z_before_m": z0})
        columns = [time_column(), *joint_columns(sim, [joint]), *target_columns(sim, [info.name])]
        if robot.has_floating_base:
            columns.append(base_z_column())
        columns += sensor_columns(sim, sensors)
        rec = Recorder(ctx.open_csv([c.name for c in columns]), columns)
        ctx.progress.start(params.steps, f"joint-step {joint}")
        sim.send(command)
        rec.record(sim)
        for _ in range(params.steps):
            sim.step()
            rec.record(sim)
            ctx.progress.advance()
        sim.forward()
        final = float(sim.q[idx_q])
        error = final - targets[info.name]
        ctx.values.update({"final_rad": final, "error_rad": error, "base_z_final_m": sim.base_z_m,
                           "steps": sim.n_steps, "simulated_time_s": sim.time_s})
        lines = [
            f"joint {joint}: before {before:+.5f} rad, target {targets[info.name]:+.5f} rad, "
            f"final {final:+.5f} rad (error {error:+.2e} rad)",
            f"steps {sim.n_steps}, simulated time {sim.time_s:.3f} s",
        ]
        if robot.has_floating_base:
            lines.append(f"base height: before {z0:.4f} m, final {sim.base_z_m:.4f} m")
        lines.append(f"MuJoCo warnings: {sim.warnings or 'none'}")
        if params.models.hidden or params.models.controller_model:
            lines.append(models_line(models.section()) + " (not used: joint-step commands MuJoCo's "
                         "position actuators)")
        return Outcome(True, tuple(lines))

    return work


#: The ``mbctl joint-step`` job.
JOINT_STEP = Job("joint-step", prepare)
