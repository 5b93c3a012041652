"""The ``mbctl xcheck`` job: cross-validate a robot's Pinocchio model against its MuJoCo plant.

The pair is loaded without the load-time agreement check (the cross-check report carries the
findings instead). The run folder gets ``crosscheck.json`` (every quantity, state and note) and
the runner's ``report.json``; ``--json FILE`` also writes the cross-check report to FILE (its
folder is checked writable before any work).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mbctl.jobs.runner import Job, Outcome, RunContext, Work, check_output_file
from mbctl.limits import MAX_XCHECK_STATES, check_limit
from mbctl.robots.crosscheck import crosscheck
from mbctl.robots.exceptions import RobotError
from mbctl.robots.registry import load_robot
from mbctl.sim.atomic import write_json_atomic


@dataclass(frozen=True)
class XcheckParams:
    """What ``mbctl xcheck`` runs.

    Attributes:
        robot: Known robot name or MJCF robot file (Pinocchio reads it unless ``pin_model``).
        scene: Scene MJCF for MuJoCo that includes the robot (default: the robot's own).
        states: Number of random states (edge states are added).
        seed: Seed of the random states.
        json_path: Also write the cross-check report as JSON to this file, or None.
        pin_model: Alternative file (MJCF or URDF) for the Pinocchio side, or None.
        gravity: Switch on the robot's gravity (the 2-link arm's is off by default).
        model_dir: Explicit Menagerie model directory for a known robot.
        analytic: "mujoco" (the Pinocchio model built from MuJoCo's compiled model) or "parser"
            (Pinocchio's own parser on the robot file: the independent path).
        roots: Bodies whose trees are the robot (default: the trees the actuators drive).
    """

    robot: str
    scene: str | None = None
    states: int = 100
    seed: int = 0
    json_path: Path | None = None
    pin_model: Path | None = None
    gravity: bool = False
    model_dir: str | None = None
    analytic: str = "mujoco"
    roots: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.states < 0:
            raise RobotError(f"states must be >= 0; got {self.states}")
        check_limit("--states", self.states, MAX_XCHECK_STATES, advice="split the states over seeds "
                    "(`mbctl sweep xcheck --param states=N --seeds K`)")
        if self.seed < 0:
            raise RobotError(f"seed must be >= 0; got {self.seed}")


def prepare(params: XcheckParams) -> Work:
    """Check the --json path and load the pair (no output yet).

    Raises:
        OutputError: The --json file's folder cannot be written.
        ToolkitError: The robot cannot be found or loaded.
    """
    if params.json_path is not None:
        check_output_file(params.json_path)
    robot = load_robot(
        params.robot,
        params.scene,
        gravity=True if params.gravity else None,
        model_dir=params.model_dir,
        pin_model_file=params.pin_model,
        check=False,
        analytic=params.analytic,
        roots=params.roots,
    )

    def work(ctx: RunContext) -> Outcome:
        ctx.progress.start(params.states, f"xcheck {robot.name}")
        report = crosscheck(robot, n_states=params.states, seed=params.seed, progress=ctx.progress.set)
        ctx.progress.stop()
        data = report.to_dict()
        write_json_atomic(ctx.path("crosscheck.json", "crosscheck"), data)
        if params.json_path is not None:
            write_json_atomic(params.json_path, data)
        ctx.values.update({
            "analytic_model": robot.source.analytic,
            "passed": report.passed,
            "failed": list(report.failed),
            "not_compared": list(report.not_compared),
            "states_per_second": report.states_per_second,
        })
        return Outcome(report.passed, (report.to_text(),),
                       "every compared quantity within its tolerance")

    return work


#: The ``mbctl xcheck`` job.
XCHECK = Job("xcheck", prepare)
