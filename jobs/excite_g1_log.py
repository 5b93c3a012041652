"""The G1 excitation's per-cycle record: the identification log's row, the balance watch, the fall, the plot.

:class:`ExciteLog` is the control loop's ``on_step``. Each cycle it writes the log's row and
measures the balance (:mod:`mbctl.jobs.excite_g1_balance`), from what the plant gives:

* in-process, the plant's monitor (:class:`~mbctl.sim.monitor.PlantMonitor`): the actuators'
  torques, the feet's contact flags and wrenches (and the CoP from them), contacts elsewhere, the
  robot's CoM and whether it fell by the G1's rule (:data:`~mbctl.robots.g1.G1_FALL`);
* over DDS, the controller: the torques it commanded, the feet it held on the ground, the CoP its
  QP planned, the CoM of the estimated state, and a fall when the estimated pelvis is below the
  G1's fall height (the bridge's truth log, when given, checks the run afterwards).

It ends the run (returns True) once the robot fell.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mbctl.control.estimation import LegKinematicsEstimator
from mbctl.control.wbc import Standing
from mbctl.jobs.excite_g1_balance import (
    SUPPORT_FORCE_N,
    Balance,
    BalanceWatch,
    SupportPolygon,
    measured_cop_W,
)
from mbctl.jobs.ident_log import command_row, log_row
from mbctl.jobs.plots import new_figure
from mbctl.jobs.runner import RunContext
from mbctl.robots.commands import Command
from mbctl.robots.g1 import G1_FALL
from mbctl.robots.interface import RobotState
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.recorder import CsvStream


class ExciteLog:
    """Each control cycle: the identification log's row, the balance and the fall.

    Kept for the report and the plot: times [s], the CoM reference and the CoM (3,) [m] (the
    plant's in-process, the estimated state's over DDS), the feet's normal forces [N] (measured, or
    the QP's over DDS), the torques [N m] and the balance margin [m].

    Args:
        csv: The log's CSV stream (the header of :func:`~mbctl.jobs.ident_log.header`).
        wb: The standing whole-body controller (its contacts and solution over DDS).
        com_ref: Gives the schedule's CoM reference (3,) [m] this cycle.
        polygon: The feet's soles on the controller's model.
        watch: The balance watch.
        monitor: The plant's monitor (in-process), or None (over DDS).
        tick: Called once per cycle (the progress bar).
        estimator: The plant's base-state estimator (over DDS, or ``--estimate``), told each cycle
            which feet the controller holds on the ground (a lifted foot is no reference), or None.
    """

    def __init__(self, csv: CsvStream, wb: Standing, com_ref: Callable[[], np.ndarray],
                 polygon: SupportPolygon, watch: BalanceWatch, monitor: PlantMonitor | None,
                 tick: Callable[[], None], estimator: LegKinematicsEstimator | None = None):
        self.csv, self.wb, self.com_ref_of, self.polygon = csv, wb, com_ref, polygon
        self.watch, self.monitor, self.tick, self.estimator = watch, monitor, tick, estimator
        self._held: dict[str, bool] = {}
        self.feet = tuple(wb.controller.contacts)
        self.t: list[float] = []
        self.com_ref: list[np.ndarray] = []
        self.com: list[np.ndarray] = []
        self.fz: list[np.ndarray] = []
        self.tau: list[np.ndarray] = []
        self.margin: list[float] = []
        self.rows_with_other_contacts = 0
        self.fall_reason: str | None = None
        self.fall_time_s: float | None = None

    def on_step(self, k: int, state: RobotState, reference: object, command: Command) -> bool:
        """Write cycle ``k``'s row and watch the balance; True (end the run) once the robot fell."""
        com_model, vcom = self.polygon.update(state.q, state.v)
        if self.monitor is not None:
            balance, com = self._measured(state, vcom)
        else:
            balance, com = self._commanded(state, command, com_model, vcom), com_model
        self.watch.observe(balance)
        self.t.append(state.time_s)
        self.com_ref.append(self.com_ref_of().copy())
        self.com.append(com)
        self.margin.append(balance.margin_m)
        held = {f: cs.active for f, cs in self.wb.controller.contacts.items()}
        if self.estimator is not None and held != self._held:  # for the next state's estimate
            self.estimator.set_contacts(held)
            self._held = held
        self.tick()
        return self.fall_reason is not None

    def _measured(self, state: RobotState, vcom: np.ndarray) -> tuple[Balance, np.ndarray]:
        monitor = self.monitor
        assert monitor is not None  # noqa: S101 - called in-process only
        self.csv.write(log_row(state, monitor))
        self.rows_with_other_contacts += monitor.contacts_elsewhere > 0
        wrenches = monitor.wrenches_W
        self.fz.append(wrenches[:, 2].copy())
        self.tau.append(monitor.joint_torques)
        if monitor.fall_reason is not None and self.fall_reason is None:
            self.fall_reason, self.fall_time_s = monitor.fall_reason, monitor.fall_time_s
        feet = [f for f, w in zip(self.feet, wrenches, strict=True) if w[2] >= SUPPORT_FORCE_N]
        floor_z = float(np.mean([self.polygon.sole_W(f)[:, 2].mean() for f in feet])) if feet else 0.0
        origins = np.array([self.polygon.body_origin_W(f) for f in self.feet])
        cop = measured_cop_W(wrenches, origins, floor_z)
        return self.polygon.margins(state.time_s, monitor.com_W, vcom, feet, cop), monitor.com_W

    def _commanded(self, state: RobotState, command: Command, com: np.ndarray, vcom: np.ndarray) -> Balance:
        ctrl = self.wb.controller
        held = np.array([cs.active for cs in ctrl.contacts.values()])
        self.csv.write(command_row(state, command.values, held))
        self.tau.append(np.array(command.values))
        solution = ctrl.solution
        totals, cops = solution.force_totals_W, solution.cop_W
        fz = np.array([totals[f][2] for f in self.feet])
        self.fz.append(fz)
        feet = [f for f, cs in ctrl.contacts.items() if cs.active and cs.weight > 0.0]
        loaded = [(fz[i], cops[f]) for i, f in enumerate(self.feet) if fz[i] > 1e-6]
        cop = sum(w * c for w, c in loaded) / sum(w for w, _ in loaded) if loaded else None
        base_z = float(state.q[2])
        if base_z < G1_FALL.base_min_z_m and self.fall_reason is None:
            self.fall_reason = f"estimated pelvis at {base_z:.3f} m (below {G1_FALL.base_min_z_m} m)"
            self.fall_time_s = state.time_s
        return self.polygon.margins(state.time_s, com, vcom, feet, cop)


def plot(ctx: RunContext, log: ExciteLog, bodies: tuple[str, ...], joints: tuple[str, ...],
         fell: str | None, measured: bool) -> None:
    """CoM (reference dashed), the feet's normal forces, the most loaded joints' torques, the balance."""
    from mbctl.jobs.excite_g1_balance import SCALE_MARGIN_M, STOP_MARGIN_M

    t = np.asarray(log.t)
    fig, axes = new_figure(4, 1, (12.0, 11.0), layout="constrained")
    com, ref = np.asarray(log.com), np.asarray(log.com_ref)
    for i, (axis, color) in enumerate(zip("xyz", ("tab:red", "tab:green", "tab:blue"), strict=True)):
        axes[0][0].plot(t, (com[:, i] - ref[0, i]) * 1e3, color=color, lw=1.2, label=f"CoM {axis}")
        axes[0][0].plot(t, (ref[:, i] - ref[0, i]) * 1e3, "--", color=color, lw=0.8)
    axes[0][0].set_ylabel("CoM - start (mm)")
    where = "measured in MuJoCo" if measured else "of the estimated state"
    axes[0][0].set_title(f"CoM {where} (solid) and its reference (dashed)"
                         + (f"; FELL: {fell}" if fell else ""), fontsize=10)
    fz = np.asarray(log.fz)
    for k, b in enumerate(bodies):
        axes[1][0].plot(t, fz[:, k], lw=1.0, label=b)
    axes[1][0].set_ylabel("normal force (N)")
    axes[1][0].set_title("contact force on each foot (" + ("MuJoCo" if measured else "the QP's plan") + ")",
                         fontsize=10)
    tau = np.asarray(log.tau)
    for i in np.argsort(-np.abs(tau).max(0))[:6]:
        axes[2][0].plot(t, tau[:, i], lw=0.9, label=joints[i])
    axes[2][0].set_ylabel(("applied" if measured else "commanded") + " torque (N m)")
    axes[2][0].set_title("the six most loaded joints", fontsize=10)
    margin = np.clip(np.asarray(log.margin) * 1e3, -50.0, None)
    axes[3][0].plot(t, margin, lw=1.0, color="k", label="balance margin")
    axes[3][0].axhline(SCALE_MARGIN_M * 1e3, color="tab:orange", ls="--", lw=0.8, label="scale below")
    axes[3][0].axhline(STOP_MARGIN_M * 1e3, color="tab:red", ls="--", lw=0.8, label="stop below")
    axes[3][0].set_ylabel("margin (mm)")
    axes[3][0].set_xlabel("time (s)")
    axes[3][0].set_title("the CoM's capture point and the CoP: distance to the support's edge (the worse)",
                         fontsize=10)
    for r in range(4):
        axes[r][0].grid(True, alpha=0.3)
        axes[r][0].legend(fontsize=8, loc="upper right", ncol=3)
    ctx.save_figure(fig, "excite.png")
