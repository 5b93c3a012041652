"""The ``mbctl demo`` job: the 2-link torque arm draws a Cartesian square.

Pipeline: a square in the arm's plane (``planners.cartesian.square_path``), timed by a
jerk-limited ruckig law that stops at each corner (``time_path``), converted to joints by the
arm's analytic IK and Jacobian (``to_joint_trajectory``), tracked on the MuJoCo plant by a
controller from ``mbctl.control`` through the control loop. The Cartesian error is measured on
the plant: the end-effector site position from MuJoCo's kinematics at each logged
configuration, against the Cartesian reference at the same time.

Controllers (``--compare`` runs them all on the same reference): ``pd`` (joint PD, gains from
omega, zeta and the joint inertia at the start), ``pd_gravity`` (the same plus g(q)),
``ct`` (joint-space computed torque) and ``task_ct`` (task-space computed torque on x-y).

Model error (``--model-error PCT``): the controller's Pinocchio model has every link mass and
rotational inertia scaled by ``1 + PCT/100`` (the plant is unchanged), so model and plant
disagree and the computed-torque cancellation is imperfect.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.controller import TaskReference
from mbctl.control.exceptions import ControllerSetupError
from mbctl.control.gains import gains_from_frequency
from mbctl.control.ik.two_link import ElbowBranch, TwoLinkArm
from mbctl.control.loop import RunLog, presample, run
from mbctl.control.pd import JointPD
from mbctl.control.pd_gravity import PDGravity
from mbctl.control.task_space import TaskSpaceComputedTorque
from mbctl.jobs.output import new_figure, save_figure, site_positions, write_columns_csv
from mbctl.planners.cartesian import (
    CartesianTrajectory,
    PathLimits,
    square_path,
    time_path,
    to_joint_trajectory,
)
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.atomic import write_json_atomic
from mbctl.sim.report import execution_report
from mbctl.sim.simulator import Simulator

CONTROLLERS = ("pd", "pd_gravity", "ct", "task_ct")
SITE = "end_effector"


@dataclass(frozen=True)
class DemoConfig:
    """Settings of the square demo.

    Attributes:
        controller: One of ``CONTROLLERS``.
        center_m: Square centre (x, y) [m] in the world frame.
        side_m: Side length [m].
        max_speed_m_s: Path speed limit [m/s].
        max_acceleration_m_s2: Tangential acceleration limit [m/s^2].
        max_jerk_m_s3: Path jerk limit [m/s^3].
        omega_rad_s: Closed-loop natural frequency of every controller [rad/s].
        zeta: Damping ratio [-].
        settle_s: Extra time after the square [s] (the reference holds the last corner).
        duration_s: Run length [s]; None runs the whole square plus ``settle_s``.
        model_error_pct: Link masses and inertias of the controller's model off by this [%].
        gravity: In-plane gravity (-y) on in both engines.
        branch: Elbow branch of the IK ("up" or "down").
    """

    controller: str = "ct"
    center_m: tuple[float, float] = (0.30, 0.25)
    side_m: float = 0.2
    max_speed_m_s: float = 0.5
    max_acceleration_m_s2: float = 3.0
    max_jerk_m_s3: float = 40.0
    omega_rad_s: float = 30.0
    zeta: float = 1.0
    settle_s: float = 0.2
    duration_s: float | None = None
    model_error_pct: float = 0.0
    gravity: bool = True
    branch: str = "down"

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLERS:
            raise ControllerSetupError(
                f"controller {self.controller!r} is unknown; choose one of {', '.join(CONTROLLERS)}"
            )
        if self.duration_s is not None and not (np.isfinite(self.duration_s) and self.duration_s > 0):
            raise ControllerSetupError(f"duration_s must be > 0 [s]; got {self.duration_s}")
        if not (np.isfinite(self.model_error_pct) and self.model_error_pct > -100):
            raise ControllerSetupError(
                f"model_error_pct must be a finite percentage > -100; got {self.model_error_pct}"
            )
        if self.branch not in ("up", "down"):
            raise ControllerSetupError(f"branch must be 'up' or 'down'; got {self.branch!r}")


@dataclass(frozen=True)
class SquareReference:
    """The square as a Cartesian trajectory and the matching joint trajectory (same grid)."""

    cartesian: CartesianTrajectory
    joints: JointTrajectory


@dataclass(frozen=True, eq=False)
class Tracking:
    """One controller's run on the square, measured on the plant.

    Attributes:
        controller: Controller name.
        rms_error_m: RMS of the Cartesian error norm |p_ref - p| [m].
        max_error_m: Largest Cartesian error norm [m].
        joint_rms_error_rad: RMS of the joint error over all joints and cycles [rad].
        saturated_cycles: Cycles in which the controller clipped a torque.
        saturations: Clipped cycles per joint.
        model_error_pct: The controller model's mass error [%].
        t_s: Cycle times (N,) [s].
        p_ref: Reference positions (N, 2) [m].
        p: Measured positions (N, 2) [m].
        log: The control loop's log.
    """

    controller: str
    rms_error_m: float
    max_error_m: float
    joint_rms_error_rad: float
    saturated_cycles: int
    saturations: dict[str, int]
    model_error_pct: float
    t_s: np.ndarray = field(repr=False)
    p_ref: np.ndarray = field(repr=False)
    p: np.ndarray = field(repr=False)
    log: RunLog = field(repr=False)

    def row(self) -> dict[str, Any]:
        """Scalar results for tables and the JSON report."""
        return {
            "controller": self.controller,
            "model_error_pct": self.model_error_pct,
            "rms_error_m": self.rms_error_m,
            "max_error_m": self.max_error_m,
            "joint_rms_error_rad": self.joint_rms_error_rad,
            "saturated_cycles": self.saturated_cycles,
            "saturations": self.saturations,
        }


def scale_masses(model: pin.Model, factor: float) -> pin.Model:
    """A copy of ``model`` with every body's mass and rotational inertia times ``factor``.

    Centres of mass and rotor armature are unchanged (armature is a motor property).
    """
    out = model.copy()
    for i in range(1, len(out.inertias)):
        inertia = out.inertias[i]
        out.inertias[i] = pin.Inertia(inertia.mass * factor, inertia.lever, inertia.inertia * factor)
    return out


def square_reference(robot: Robot, config: DemoConfig, dt_s: float) -> SquareReference:
    """Plan the square: Cartesian path, ruckig timing, analytic IK to joints.

    Raises:
        PlanningError: The square leaves the workspace or crosses a singularity.
    """
    arm = TwoLinkArm.from_robot(robot)
    data = robot.pin_model.createData()
    pin.framesForwardKinematics(robot.pin_model, data, robot.neutral_q())
    z = float(data.oMf[robot.frame_id(SITE)].translation[2])  # the arm's plane
    center = (config.center_m[0], config.center_m[1], z)
    path = square_path(center, config.side_m)
    limits = PathLimits(config.max_speed_m_s, config.max_acceleration_m_s2, config.max_jerk_m_s3)
    cart = time_path(path, limits, dt_s)
    branch = ElbowBranch(config.branch)
    joints = tuple(robot.joints)
    q_traj = to_joint_trajectory(
        cart,
        lambda p: arm.inverse_kinematics(p, branch),
        arm.jacobian,
        joints,
        task_dims=2,
    )
    return SquareReference(cart, q_traj)


def make_controller(
    name: str, robot: Robot, config: DemoConfig, q0: np.ndarray, pin_model: pin.Model | None = None
):  # noqa: ANN201 - one of the controller classes
    """Build controller ``name`` with gains from ``config.omega_rad_s`` and ``config.zeta``.

    PD gains use the joint inertias ``diag M(q0)`` of the (possibly perturbed) model; the
    computed-torque gains are per unit inertia.
    """
    model = pin_model if pin_model is not None else robot.pin_model
    if name in ("pd", "pd_gravity"):
        inertia = np.diag(pin.crba(model, model.createData(), q0)).copy()
        gains = gains_from_frequency(config.omega_rad_s, config.zeta, inertia)
        if name == "pd":
            return JointPD(robot, gains)
        return PDGravity(robot, gains, pin_model=model)
    gains = gains_from_frequency(config.omega_rad_s, config.zeta)
    if name == "ct":
        return ComputedTorque(robot, gains, pin_model=model)
    if name == "task_ct":
        return TaskSpaceComputedTorque(robot, gains, SITE, "xy", pin_model=model)
    raise ControllerSetupError(f"controller {name!r} is unknown; choose one of {CONTROLLERS}")


def track_square(
    robot: Robot,
    reference: SquareReference,
    config: DemoConfig,
    controller_name: str | None = None,
    model_error_pct: float | None = None,
) -> tuple[Tracking, Simulator]:
    """Run one controller on the square from rest at its first corner; measure on the plant."""
    name = controller_name or config.controller
    pct = config.model_error_pct if model_error_pct is None else model_error_pct
    pin_model = scale_masses(robot.pin_model, 1.0 + pct / 100.0) if pct else None
    q_traj, cart = reference.joints, reference.cartesian
    sim = Simulator(robot)
    sim.reset(q=q_traj.q[0])
    controller = make_controller(name, robot, config, q_traj.q[0], pin_model)
    duration = config.duration_s or (q_traj.duration_s + config.settle_s)
    n = max(1, int(round(duration / sim.control_period_s)))
    t_rel = np.arange(n) * sim.control_period_s
    idx = np.minimum(np.rint(t_rel / cart.dt_s).astype(int), len(cart.t_s) - 1)
    at_end = t_rel >= cart.t_s[-1]
    p_ref = cart.p[idx, :2]
    if name == "task_ct":
        v_ref = np.where(at_end[:, None], 0.0, cart.v[idx, :2])
        a_ref = np.where(at_end[:, None], 0.0, cart.a[idx, :2])
        refs = [TaskReference(p_ref[k], v_ref[k], a_ref[k]) for k in range(n)]
        period = sim.control_period_s

        def reference_fn(t_s: float) -> TaskReference:
            return refs[min(int(round(t_s / period)), n - 1)]

        log = run(sim, controller, reference_fn, duration)
        q_ref, _, _ = presample(q_traj, t_rel, controller.joints)
    else:
        log = run(sim, controller, q_traj, duration)
        q_ref = log.reference
    p = site_positions(robot, log.q, SITE)[:, :2]
    err = np.linalg.norm(p_ref - p, axis=1)
    joint_err = q_ref - log.q[:, controller.joint_map.idx_q]
    result = Tracking(
        name,
        float(np.sqrt(np.mean(err**2))),
        float(np.max(err)),
        float(np.sqrt(np.mean(joint_err**2))),
        int(controller.saturation.saturated_cycles),
        controller.saturation.by_joint(),
        float(pct),
        log.t_s,
        p_ref,
        p,
        log,
    )
    return result, sim


@dataclass(frozen=True)
class DemoResult:
    """Outcome of ``run_demo``.

    Attributes:
        main: The tracking run of the chosen controller (with the configured model error).
        compare: Every controller on the same reference (with ``--compare``).
        exact_model: The same controller with an exact model (with ``--model-error``).
        files: Written files by role.
    """

    main: Tracking
    compare: tuple[Tracking, ...]
    exact_model: Tracking | None
    files: dict[str, Path]

    def summary(self) -> str:
        """Human-readable results with units."""
        m = self.main
        lines = [
            f"controller {m.controller}"
            + (f" (model masses {m.model_error_pct:+g} %)" if m.model_error_pct else "")
            + f": Cartesian RMS error {m.rms_error_m * 1e3:.4f} mm, max {m.max_error_m * 1e3:.4f} mm, "
            f"joint RMS {m.joint_rms_error_rad:.3e} rad, saturated cycles {m.saturated_cycles}",
        ]
        if self.exact_model is not None:
            e = self.exact_model
            ratio = m.rms_error_m / e.rms_error_m if e.rms_error_m > 0 else float("inf")
            lines.append(
                f"exact model: RMS {e.rms_error_m * 1e3:.4f} mm, max {e.max_error_m * 1e3:.4f} mm; "
                f"with {m.model_error_pct:+g} % mass error the RMS error is {ratio:.1f}x larger"
            )
        if self.compare:
            lines.append(f"{'controller':<12} {'RMS [mm]':>10} {'max [mm]':>10} "
                         f"{'joint RMS [rad]':>16} {'saturated':>10}")
            for t in self.compare:
                lines.append(
                    f"{t.controller:<12} {t.rms_error_m * 1e3:>10.4f} {t.max_error_m * 1e3:>10.4f} "
                    f"{t.joint_rms_error_rad:>16.3e} {t.saturated_cycles:>10d}"
                )
        lines.append("wrote " + ", ".join(str(p) for p in self.files.values()))
        return "\n".join(lines)


def run_demo(
    config: DemoConfig,
    output_dir: str | os.PathLike,
    *,
    compare: bool = False,
    robot: Robot | None = None,
) -> DemoResult:
    """Run the square demo, write CSV, JSON report and PNG into ``output_dir``.

    Args:
        config: Demo settings.
        output_dir: Directory for ``demo.csv``, ``demo_report.json`` and ``demo.png``.
        compare: Also run every controller (exact model) on the same reference.
        robot: The 2-link torque arm (default: loaded with ``config.gravity``).

    Raises:
        ControllerSetupError: Bad settings.
        PlanningError: A square outside the workspace.
        SimulationDiverged: The plant diverged.
    """
    robot = robot or load_robot("two_link_torque", gravity=config.gravity)
    dt = robot.timestep_s
    reference = square_reference(robot, config, dt)
    main, sim = track_square(robot, reference, config)
    exact = None
    if config.model_error_pct:
        exact, _ = track_square(robot, reference, config, model_error_pct=0.0)
    runs: list[Tracking] = []
    if compare:
        for name in CONTROLLERS:
            same = name == main.controller and not config.model_error_pct
            runs.append(main if same else track_square(robot, reference, config, name, 0.0)[0])
    out = Path(output_dir)
    files = {
        "csv": _write_csv(out / "demo.csv", robot, main),
        "plot": _plot(out / "demo.png", main, exact, tuple(runs)),
    }
    report = execution_report(
        sim,
        "demo",
        inputs={**asdict(config), "compare": compare},
        reference={
            "duration_s": reference.cartesian.duration_s,
            "samples": len(reference.cartesian.t_s),
            "corners_m": [list(map(float, reference.cartesian.p[i, :2]))
                          for i in reference.cartesian.corner_indices],
        },
        values=main.row(),
        exact_model=exact.row() if exact else None,
        compare=[t.row() for t in runs],
        outputs={k: str(v) for k, v in files.items()},
    )
    files["report"] = write_json_atomic(out / "demo_report.json", report)
    return DemoResult(main, tuple(runs), exact, files)


def _write_csv(path: Path, robot: Robot, t: Tracking) -> Path:
    log = t.log
    cols: dict[str, np.ndarray] = {"time_s": t.t_s}
    joints = list(robot.joints)
    for i, j in enumerate(joints):
        if log.reference.shape[1] == len(joints) and t.controller != "task_ct":
            cols[f"q_ref_{j}_rad"] = log.reference[:, i]
        cols[f"q_{j}_rad"] = log.q[:, i]
        cols[f"v_{j}_rad_s"] = log.v[:, i]
    for i, a in enumerate(robot.actuators):
        cols[f"tau_{a}_N_m"] = log.command[:, i]
    cols["p_ref_x_m"], cols["p_ref_y_m"] = t.p_ref[:, 0], t.p_ref[:, 1]
    cols["p_x_m"], cols["p_y_m"] = t.p[:, 0], t.p[:, 1]
    cols["error_m"] = np.linalg.norm(t.p_ref - t.p, axis=1)
    return write_columns_csv(path, cols)


def _plot(path: Path, main: Tracking, exact: Tracking | None, runs: tuple[Tracking, ...]) -> Path:
    fig, axes = new_figure(1, 2, (12.0, 5.0))
    ax_path, ax_err = axes[0]
    ax_path.plot(main.p_ref[:, 0], main.p_ref[:, 1], "k--", lw=1.2, label="reference")
    shown = runs or ((main, exact) if exact else (main,))
    for t in shown:
        if t is None:
            continue
        label = t.controller + (f" (mass {t.model_error_pct:+g} %)" if t.model_error_pct else "")
        ax_path.plot(t.p[:, 0], t.p[:, 1], lw=1.0, label=label)
        ax_err.semilogy(t.t_s, np.maximum(np.linalg.norm(t.p_ref - t.p, axis=1), 1e-9) * 1e3,
                        lw=1.0, label=label)
    ax_path.set_aspect("equal")
    ax_path.set_xlabel("x [m]")
    ax_path.set_ylabel("y [m]")
    ax_path.set_title("end-effector path (plant)")
    ax_path.legend(fontsize=8)
    ax_err.set_xlabel("time [s]")
    ax_err.set_ylabel("Cartesian error [mm]")
    ax_err.set_title("tracking error |p_ref - p|")
    ax_err.grid(True, which="both", alpha=0.3)
    ax_err.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)
