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
disagree and the computed-torque cancellation is imperfect. The PD controllers use the model
for their gains only (``kp = I omega^2``, ``kd = 2 zeta I omega``, I the model's joint inertia at
the start; PD + gravity also for g(q)): heavier model masses make them stiffer, and on the plant
the loop runs at ``omega sqrt(I_model / I_plant)``, so plain PD tracks *better* as the masses
grow (measured: 24.2 mm exact, 17.2 mm at +40 %; the exact model at 35.4 rad/s gives 17.1 mm).
That is a gain change, not a model-cancellation error; the job says so (:func:`pd_gain_note`).
The model options (``--payload``, ``--plant-error``, ``--controller-model``;
:mod:`mbctl.jobs.model_options`) change the plant instead, or give the controller a model from a
file (an identified one).
"""

from __future__ import annotations

from dataclasses import dataclass, field
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
from mbctl.jobs.choices import CONTROLLERS
from mbctl.jobs.demo_errors import SquareErrors
from mbctl.jobs.model_options import ModelOptions, build_models, models_line
from mbctl.jobs.plots import new_figure
from mbctl.jobs.recording import LoopRows, PlantSite, command_columns
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.limits import check_duration
from mbctl.planners.cartesian import CartesianTrajectory, PathLimits, time_path, to_joint_trajectory
from mbctl.planners.paths import square_path
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.edits import scale_masses
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.simulator import Simulator
from mbctl.sim.video import add_markers

#: Full names for plots and summaries.
LABELS = {"pd": "joint PD", "pd_gravity": "PD + gravity", "ct": "computed torque",
          "task_ct": "task-space computed torque"}
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
        compare: Also run every controller (exact model) on the same reference.
        max_rms_error_m: Bound on the chosen controller's Cartesian RMS error [m] (exit 1 above
            it); None: no bound.
        plant: Hidden plant changes and the controller's model file.
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
    compare: bool = False
    max_rms_error_m: float | None = None
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLERS:
            raise ControllerSetupError(
                f"controller {self.controller!r} is unknown; choose one of {', '.join(CONTROLLERS)}"
            )
        if self.duration_s is not None and not (np.isfinite(self.duration_s) and self.duration_s > 0):
            raise ControllerSetupError(f"duration_s must be > 0 [s]; got {self.duration_s}")
        check_duration(self.duration_s)
        if not (np.isfinite(self.model_error_pct) and self.model_error_pct > -100):
            raise ControllerSetupError(
                f"model_error_pct must be a finite percentage > -100; got {self.model_error_pct}"
            )
        for name in ("side_m", "max_speed_m_s", "max_acceleration_m_s2", "max_jerk_m_s3", "omega_rad_s",
                     "zeta"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ControllerSetupError(f"{name} must be finite and > 0; got {value}")
        if self.max_rms_error_m is not None and not self.max_rms_error_m > 0:
            raise ControllerSetupError(f"max_rms_error_m must be > 0 [m]; got {self.max_rms_error_m}")
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
        rms_error_m: RMS of the Cartesian error norm |p_ref - p| [m] over every cycle.
        max_error_m: Largest Cartesian error norm [m] over every cycle.
        joint_rms_error_rad: RMS of the joint error over all joints and cycles [rad].
        saturated_cycles: Cycles in which the controller clipped a torque.
        saturations: Clipped cycles per joint.
        model_error_pct: The controller model's mass error [%].
        t_s: Times (R,) [s] of the loop log's rows (every cycle, or every ``log.stride``-th and the last).
        p_ref: Reference positions (R, 2) [m] at those rows.
        p: Measured positions (R, 2) [m] at those rows.
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


def path_points(reference: SquareReference, n: int = 80) -> np.ndarray:
    """About ``n`` points (k, 3) [m] in W along the reference square, corners included."""
    p = reference.cartesian.p
    return np.vstack([p[:: max(1, len(p) // n)], p[-1:]])


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
    ctx: RunContext | None = None,
    controller_model: pin.Model | None = None,
) -> tuple[Tracking, Simulator]:
    """Run one controller on the square from rest at its first corner; measure on the plant.

    With ``ctx``, the simulator is the run's plant (its report sections) and every cycle streams
    a row to the run's CSV as it happens. ``robot`` is the plant; the controller uses
    ``controller_model`` (default: the plant's own model), scaled by the model error.
    """
    name = controller_name or config.controller
    pct = config.model_error_pct if model_error_pct is None else model_error_pct
    base = controller_model if controller_model is not None else robot.pin_model
    pin_model = scale_masses(base, 1.0 + pct / 100.0) if pct else controller_model
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
    q_ref_task = presample(q_traj, t_rel, controller.joints)[0] if name == "task_ct" else None
    errors = SquareErrors(PlantSite(robot, SITE), p_ref, q_ref_task, controller.joint_map.idx_q,
                           sim.control_period_s, sim.time_s)

    def on_step(k: int, state: RobotState, ref: Any, command: object) -> None:
        errors(state)

    if ctx is not None:
        points = path_points(reference)  # the reference square, drawn in the video
        planned = np.array([robot.plant_qpos(q) for q in q_traj.q[:: max(1, len(q_traj.q) // 100)]])
        ctx.attach(sim, overlay=lambda scene: add_markers(scene, points, 0.004, (0.1, 0.8, 0.2, 1.0)),
                   frame_qpos=planned, frame_points_W=points)

        def extra(state: RobotState) -> list[float]:
            k, p, e = errors(state)
            return [*p_ref[k], p[0], p[1], e]

        width = 2 if name == "task_ct" else len(controller.joints)
        ref_names = ([f"p_ref_{a}_m" for a in "xy"] if name == "task_ct" else
                     [f"q_ref_{j}_rad" for j in controller.joints])
        header = LoopRows.header(robot, ref_names, command_columns(list(robot.actuators), "N_m"),
                                 ["p_ref_x_m", "p_ref_y_m", "p_x_m", "p_y_m", "error_m"])
        if name == "task_ct":  # the reference *is* p_ref: do not write it twice
            header = header[:1] + header[3:]
            width = 0
        ctx.progress.start(n, f"demo ({LABELS[name]})")
        on_step = LoopRows(ctx.open_csv(header), width, extra, ctx.progress.advance)  # type: ignore[assignment]
    if name == "task_ct":
        v_ref = np.where(at_end[:, None], 0.0, cart.v[idx, :2])
        a_ref = np.where(at_end[:, None], 0.0, cart.a[idx, :2])
        refs = [TaskReference(p_ref[k], v_ref[k], a_ref[k]) for k in range(n)]
        period = sim.control_period_s

        def reference_fn(t_s: float) -> TaskReference:
            return refs[min(int(round(t_s / period)), n - 1)]

        log = run(sim, controller, reference_fn, duration, on_step)
        joint_rms = errors.joint_rms()
    else:
        log = run(sim, controller, q_traj, duration, on_step)
        joint_rms = log.error_sums().rms_all()  # a joint trajectory's
    # the figures: every cycle's errors; the curves: the log's rows
    p = PlantSite(robot, SITE).many(log.q)[:, :2]
    result = Tracking(
        name,
        errors.rms(),
        errors.max,
        joint_rms,
        int(controller.saturation.saturated_cycles),
        controller.saturation.by_joint(),
        float(pct),
        log.row_time_s,
        p_ref[log.cycle],
        p,
        log,
    )
    return result, sim


def pd_gain_note(robot: Robot, config: DemoConfig, q0: np.ndarray) -> tuple[list[str], dict[str, Any]]:
    """Why a PD controller's error changes with the model error: its gains are scaled.

    The PD gains come from the model's joint inertia ``I_model = diag M(q0)``; the plant's is
    ``I_plant``. On the plant the loop's natural frequency is ``omega sqrt(I_model / I_plant)``.

    Returns:
        Summary lines, and the report values ``pd_gain_ratio`` and ``pd_effective_omega_rad_s``
        (per joint).
    """
    model = scale_masses(robot.pin_model, 1.0 + config.model_error_pct / 100.0)
    ratio = (np.diag(pin.crba(model, model.createData(), q0))
             / np.diag(pin.crba(robot.pin_model, robot.pin_model.createData(), q0)))
    omega = config.omega_rad_s * np.sqrt(ratio)
    joints = list(robot.joints)
    values = {"pd_gain_ratio": dict(zip(joints, ratio.tolist(), strict=True)),
              "pd_effective_omega_rad_s": dict(zip(joints, omega.tolist(), strict=True))}
    what = "its gains" + (" and g(q)" if config.controller == "pd_gravity" else "")
    lines = [
        f"why: {LABELS[config.controller]} uses the model only for {what}: kp = I omega^2, kd = 2 zeta I "
        f"omega with I the model's joint inertia at the start; masses {config.model_error_pct:+g} % make "
        f"them {'/'.join(f'{r:.2f}' for r in ratio)}x ({'/'.join(joints)}), so on the plant the loop runs "
        f"at {'/'.join(f'{w:.1f}' for w in omega)} rad/s instead of {config.omega_rad_s:g} rad/s"
        + (": stiffer" if np.all(ratio > 1) else ": softer")
        + ("; its g(q) is off too, by the same factor, and with gravity on that dominates."
           if config.controller == "pd_gravity" else
           (", hence the smaller error. That is a gain change, not a model-cancellation error "
            "(see --controller ct)." if np.all(ratio > 1) else ", hence the larger error.")),
    ]
    return lines, values


def summary_lines(main: Tracking, exact: Tracking | None, runs: tuple[Tracking, ...]) -> list[str]:
    """Human-readable results with units."""
    lines = [
        f"{LABELS[main.controller]}"
        + (f" (model masses {main.model_error_pct:+g} %)" if main.model_error_pct else "")
        + f": Cartesian RMS error {main.rms_error_m * 1e3:.4f} mm, max {main.max_error_m * 1e3:.4f} mm, "
        f"joint RMS {main.joint_rms_error_rad:.3e} rad, saturated cycles {main.saturated_cycles}",
    ]
    if exact is not None:
        ratio = main.rms_error_m / exact.rms_error_m if exact.rms_error_m > 0 else float("inf")
        lines.append(
            f"exact model: RMS {exact.rms_error_m * 1e3:.4f} mm, max {exact.max_error_m * 1e3:.4f} mm; "
            f"with {main.model_error_pct:+g} % mass error the RMS error is {ratio:.2g}x the exact model's"
        )
    if runs:
        lines.append(f"{'controller':<28} {'RMS (mm)':>10} {'max (mm)':>10} "
                     f"{'joint RMS (rad)':>16} {'saturated':>10}")
        for t in runs:
            lines.append(
                f"{LABELS[t.controller]:<28} {t.rms_error_m * 1e3:>10.4f} {t.max_error_m * 1e3:>10.4f} "
                f"{t.joint_rms_error_rad:>16.3e} {t.saturated_cycles:>10d}"
            )
    return lines


def prepare(config: DemoConfig, robot: Robot | None = None) -> Work:
    """Load the 2-link torque arm and plan the square (bad settings fail here, before any output).

    Raises:
        PlanningError: A square outside the workspace or through a singularity.
    """
    models = build_models(robot or load_robot("two_link_torque", gravity=config.gravity), config.models)
    robot, model = models.plant, models.controller_model
    reference = square_reference(robot, config, robot.timestep_s)

    def work(ctx: RunContext) -> Outcome:
        ctx.sections["reference"] = {
            "duration_s": reference.cartesian.duration_s,
            "samples": len(reference.cartesian.t_s),
            "corners_m": [list(map(float, reference.cartesian.p[i, :2]))
                          for i in reference.cartesian.corner_indices],
            # the square in W (x, y, z in the arm's plane), as the video and the web replay draw it
            "path_m": path_points(reference).tolist(),
        }
        ctx.sections["plant"] = models.section()
        main, _ = track_square(robot, reference, config, ctx=ctx, controller_model=model)
        ctx.values.update(main.row())
        exact = None
        notes: list[str] = []
        if config.model_error_pct:
            exact, _ = track_square(robot, reference, config, model_error_pct=0.0, controller_model=model)
            ctx.sections["exact_model"] = exact.row()
            if config.controller in ("pd", "pd_gravity"):
                notes, gain_values = pd_gain_note(robot, config, reference.joints.q[0])
                ctx.values.update(gain_values)
        runs: list[Tracking] = []
        if config.compare:
            for name in CONTROLLERS:
                same = name == main.controller and not config.model_error_pct
                runs.append(main if same else track_square(robot, reference, config, name, 0.0,
                                                           controller_model=model)[0])
            ctx.sections["compare"] = [t.row() for t in runs]
        plot(ctx, main, exact, tuple(runs), config)
        bound = config.max_rms_error_m
        passed = bound is None or main.rms_error_m <= bound
        lines = summary_lines(main, exact, tuple(runs)) + notes
        if config.models.hidden or config.models.controller_model:
            lines.insert(0, models_line(models.section()))
        return Outcome(passed, tuple(lines),
                       None if bound is None else f"Cartesian RMS error <= {bound * 1e3:g} mm")

    return work


#: The ``mbctl demo`` job.
DEMO = Job("demo", prepare)


def plot(ctx: RunContext, main: Tracking, exact: Tracking | None, runs: tuple[Tracking, ...],
         config: DemoConfig) -> None:
    """The path on the plane and the error over time, in mm; reference dashed, plant solid."""
    fig, axes = new_figure(1, 2, (12.0, 5.2))
    ax_path, ax_err = axes[0]
    ax_path.plot(main.p_ref[:, 0], main.p_ref[:, 1], "k--", lw=1.2, label="reference", zorder=5)
    shown = runs or tuple(t for t in (main, exact) if t is not None)
    for t in shown:
        label = LABELS[t.controller] + (f" (masses {t.model_error_pct:+g} %)" if t.model_error_pct
                                        else ("" if t is not exact else " (exact model)"))
        ax_path.plot(t.p[:, 0], t.p[:, 1], lw=1.0, label=label)
        ax_err.semilogy(t.t_s, np.maximum(np.linalg.norm(t.p_ref - t.p, axis=1), 1e-9) * 1e3,
                        lw=1.0, label=f"{label}: RMS {t.rms_error_m * 1e3:.3g} mm")
    ax_path.set_aspect("equal")
    ax_path.set_xlabel("x (m)")
    ax_path.set_ylabel("y (m)")
    ax_path.set_title("end-effector path, measured in MuJoCo")
    ax_path.legend(fontsize=8, loc="center")
    ax_err.set_xlabel("time (s)")
    ax_err.set_ylabel("Cartesian error |p_ref - p| (mm)")
    ax_err.set_title("tracking error")
    ax_err.grid(True, which="both", alpha=0.3)
    ax_err.legend(fontsize=8)
    gravity = "gravity on" if config.gravity else "gravity off"
    fig.suptitle(
        f"2-link arm, {config.side_m * 1e3:g} mm square: {LABELS[main.controller]}, "
        f"omega {config.omega_rad_s:g} rad/s, zeta {config.zeta:g}, {gravity}; "
        f"RMS {main.rms_error_m * 1e3:.3g} mm, max {main.max_error_m * 1e3:.3g} mm"
    )
    fig.tight_layout()
    ctx.save_figure(fig, "demo.png")
