"""What ``mbctl g1-wbc`` records each control cycle: the CSV row, the logs, and the report's values.

Each cycle (the control loop's ``on_step``, after the plant ran the command) puts side by side
what the QP predicted and what MuJoCo did (:class:`~mbctl.sim.monitor.PlantMonitor`): per foot the
normal and tangential force and the centre of pressure, the CoM against its reference, and the
slip of each supporting foot. Logs are preallocated arrays; the report's values are refreshed
every 50 cycles so an interrupted run keeps them.
"""

from __future__ import annotations

import math
import time
from typing import Any, NamedTuple

import numpy as np

from mbctl.control.wbc import Standing, WBCSolution
from mbctl.jobs.runner import RunContext
from mbctl.robots.commands import Command
from mbctl.robots.g1 import FEET
from mbctl.robots.interface import RobotState
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.perturb import PushSchedule
from mbctl.sim.simulator import Simulator

#: A foot supports the robot (its slip counts) when MuJoCo measures at least this fraction of
#: m g on it at full contact weight.
SUPPORT_FRACTION = 0.1

#: Cycles between refreshes of the report's values (an interrupted run keeps the last ones): 1 s
#: at 500 Hz. A refresh computes the statistics over the whole run so far (~0.75 ms late in a
#: 10 s run): every 50 cycles it was the largest cause of missed 2 ms deadlines over DDS.
VALUES_EVERY = 500

#: The first period [s] of a run, while MuJoCo's soft contacts settle from the set start pose
#: (about 80 N more than m g on the first step, decaying over ~20 ms): left out of the force-error
#: statistics and reported on its own (``contact_force_rel_error_settling_max``).
SETTLE_S = 0.05

#: A foot's columns in the CSV (QP fz, ft, CoP x, y; MuJoCo's the same; slip).
_PER_FOOT = 9
#: A foot's MuJoCo columns and slip when the plant is not observed (over DDS).
_NO_PLANT = (float("nan"),) * 5
#: What each cycle's row keeps after the CSV's columns (the record's other fields).
_EXTRA = ("t_plant", "stance", "ctrl_us", "qp_us", "slip", "cycle_us", "physics_us")


class WBCRecord(NamedTuple):
    """The cycles of a g1-wbc run recorded so far (k of them), feet in :data:`~mbctl.robots.g1.FEET` order.

    Attributes:
        t: Cycle times (k,) [s]: the time of the state the controller was given.
        t_plant: The plant's time (k,) [s] of ``com`` (later than ``t`` by the link's latency).
        com_ref: CoM reference (k, 3) [m] in W, set for time ``t``.
        com: MuJoCo's CoM (k, 3) [m] in W at ``t_plant``.
        fz_qp: Normal force per foot predicted by the QP (k, 2) [N].
        fz_mj: Normal force per foot measured in MuJoCo (k, 2) [N].
        ft_qp: Tangential force per foot, QP (k, 2) [N].
        ft_mj: Tangential force per foot, MuJoCo (k, 2) [N].
        cop_qp: Centre of pressure per foot, QP (k, 2, 2) [m] (x, y in W).
        cop_mj: Centre of pressure per foot, MuJoCo (k, 2, 2) [m].
        stance: Both feet in full contact under the QP (k,).
        slip: Largest slip of a supporting foot (k,) [m].
        z: Pelvis height (k,) [m].
        ctrl_us: Controller time per cycle (k,) [us].
        qp_us: QP solve time per cycle (k,) [us] (0 under the fallback).
        cycle_us: Wall time of each whole cycle (k,) [us]: state, controller, physics step,
            plant monitor and this record (the first cycle's is NaN).
    """

    t: np.ndarray
    t_plant: np.ndarray
    com_ref: np.ndarray
    com: np.ndarray
    fz_qp: np.ndarray
    fz_mj: np.ndarray
    ft_qp: np.ndarray
    ft_mj: np.ndarray
    cop_qp: np.ndarray
    cop_mj: np.ndarray
    stance: np.ndarray
    slip: np.ndarray
    z: np.ndarray
    ctrl_us: np.ndarray
    qp_us: np.ndarray
    cycle_us: np.ndarray


def com_tracking_error(r: WBCRecord) -> np.ndarray:
    """The plant's CoM minus the reference at the same time (k', 3) [m].

    Behind a link with latency the controller's state (and so the reference it was given) is older
    than the plant; the reference, a smooth trajectory, is interpolated at the plant's times (up to
    the last reference time). Without latency ``t_plant == t`` and this is ``com - com_ref``.
    """
    keep = r.t_plant <= r.t[-1]
    ref = np.column_stack([np.interp(r.t_plant[keep], r.t, r.com_ref[:, i]) for i in range(3)])
    return r.com[keep] - ref


class WBCLog:
    """Records a g1-wbc run cycle by cycle into preallocated arrays of ``n`` cycles."""

    def __init__(self, ctx: RunContext, wb: Standing, monitor: PlantMonitor | None,
                 pushes: PushSchedule | None, n: int, mg_n: float, q_names: list[str]):
        self.ctx, self.wb, self.monitor, self.pushes, self.mg = ctx, wb, monitor, pushes, mg_n
        ctrl = wb.controller
        header = ["time_s", "com_ref_x_m", "com_ref_y_m", "com_ref_z_m", "com_x_m", "com_y_m", "com_z_m",
                  "base_z_m", "push_fx_N", "push_fy_N"]
        for f in FEET:
            header += [f"{f}_fz_qp_N", f"{f}_ft_qp_N", f"{f}_cop_x_qp_m", f"{f}_cop_y_qp_m",
                       f"{f}_fz_mj_N", f"{f}_ft_mj_N", f"{f}_cop_x_mj_m", f"{f}_cop_y_mj_m", f"{f}_slip_m"]
        header += [f"tau_{a}_N_m" for a in ctrl.joints.actuators] + q_names
        self.csv = ctx.open_csv(header)
        # One preallocated row per cycle: the CSV's columns up to the torques, then what only the
        # record keeps; the record's fields are views. The torques and q go to the CSV only (a
        # scratch row): they are 65 of the G1's 100 columns, 0.9 GB of an hour's run kept for nothing.
        w, nf, nt = len(header), len(FEET), len(ctrl.joints.actuators)
        feet_at = header.index(f"{FEET[0]}_fz_qp_N")
        self._tau = slice(feet_at + _PER_FOOT * nf, feet_at + _PER_FOOT * nf + nt)
        self._q = slice(self._tau.stop, w)
        self._csv_row = np.zeros(w)
        kept = self._tau.start
        self._rows = np.zeros((n, kept + len(_EXTRA)))
        self._rows[:, kept + _EXTRA.index("cycle_us")] = np.nan  # the first cycle has no start
        self._feet = self._rows[:, feet_at:feet_at + _PER_FOOT * nf].reshape(n, nf, _PER_FOOT)
        self._extra = {name: kept + i for i, name in enumerate(_EXTRA)}
        self.k = 0
        self.com_from_truth = False  # with_truth replaced the estimated CoM by the plant's
        self._last_cycle_end: float | None = None
        self._home: dict[str, tuple[float, float]] = {}  # where each foot started to support
        self._points_src: object = None  # the solution's contact points, as lists per foot (_qp_feet)
        self._points: dict[str, list[list[float]]] = {}
        if monitor is not None:  # FEET's places among the monitor's contact groups and sites
            self._groups = [monitor.group_names.index(f) for f in FEET]
            self._sites = [monitor.site_names.index(f) for f in FEET]

    def record(self) -> WBCRecord:
        """The cycles recorded so far (views of the rows, but ``stance``, a bool copy)."""
        rows, feet, x = self._rows[: self.k], self._feet[: self.k], self._extra
        return WBCRecord(rows[:, 0], rows[:, x["t_plant"]], rows[:, 1:4], rows[:, 4:7],
                         feet[:, :, 0], feet[:, :, 4], feet[:, :, 1], feet[:, :, 5], feet[:, :, 2:4],
                         feet[:, :, 6:8], rows[:, x["stance"]] > 0.5, rows[:, x["slip"]], rows[:, 7],
                         rows[:, x["ctrl_us"]], rows[:, x["qp_us"]], rows[:, x["cycle_us"]])

    def _qp_feet(self, sol: WBCSolution) -> list[tuple[float, float, float, float]]:
        """Per foot (FEET order), the QP's prediction: normal, tangential force [N], CoP x, y [m] in W.

        ``sol.totals_and_cops_W`` in plain floats (the sum of the points' forces turned into W, the
        CoP of their world-z forces at their positions moved to W; 4 points a foot): about half its
        time, and this runs every cycle.
        """
        if sol.points_F is not self._points_src:
            self._points_src = sol.points_F
            self._points = {f: sol.points_F[f].tolist() for f in FEET}
        forces = sol.forces.tolist()
        out = []
        for f in FEET:
            pose = sol.foot_poses_W[f]
            (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = pose.rotation.tolist()
            sl = sol.force_slices[f]
            F = forces[sl.start:sl.stop]
            sx = sy = sz = mx = my = mz = 0.0
            for j, (px, py, pz) in enumerate(self._points[f]):
                fx, fy, fz = F[3 * j], F[3 * j + 1], F[3 * j + 2]
                sx += fx
                sy += fy
                sz += fz
                w = r20 * fx + r21 * fy + r22 * fz  # the point's force along W's z
                mx += w * px
                my += w * py
                mz += w * pz
            tx = r00 * sx + r01 * sy + r02 * sz
            ty = r10 * sx + r11 * sy + r12 * sz
            tz = r20 * sx + r21 * sy + r22 * sz
            if tz > 1e-6:
                ox, oy, _ = pose.translation.tolist()
                cx = (r00 * mx + r01 * my + r02 * mz) / tz + ox
                cy = (r10 * mx + r11 * my + r12 * mz) / tz + oy
            else:
                cx = cy = math.nan
            out.append((tz, math.hypot(tx, ty), cx, cy))
        return out

    def on_step(self, k: int, state: RobotState, reference: object, command: Command) -> bool:
        """Record cycle ``k`` (the loop's ``on_step``); True once the robot has fallen (ends the run)."""
        ctrl, mon = self.wb.controller, self.monitor
        sol = ctrl.solution
        row, x = self._rows[k], self._extra
        t = state.time_s
        # the row's first columns built as one list and stored in one assignment (a numpy store per
        # value or slice costs more than the values' arithmetic)
        # the plant's CoM in-process; over DDS the controller's (from the estimated state), replaced
        # by the bridge's truth after the run when given (with_truth)
        com = mon.com_W if mon is not None else ctrl.state.com()
        vals = [t, *self.wb.com.target.tolist(), *com.tolist(), float(state.q[2]),
                *(self.pushes.force_W[:2].tolist() if self.pushes is not None else (0.0, 0.0))]
        stance = True
        slip_max = 0.0
        qp = self._qp_feet(sol)
        if mon is not None:  # the monitor's groups and sites in FEET order, as plain numbers
            sums = mon.contact_sums
            xyz = mon.site_array_W.tolist()
        for i, f in enumerate(FEET):
            cs = ctrl.contacts[f]
            supporting = cs.active and cs.weight == 1.0
            stance = stance and supporting
            if mon is None:  # over DDS: the plant's forces and feet are not observed
                vals += (*qp[i], *_NO_PLANT)
                continue
            fx, fy, fz, mx, my, _ = sums[self._groups[i]]
            mx, my = (mx / fz, my / fz) if fz > 1e-9 else (math.nan, math.nan)  # the CoP, as contacts'
            px, py, _ = xyz[self._sites[i]]
            if supporting and fz >= SUPPORT_FRACTION * self.mg:
                hx, hy = self._home.setdefault(f, (px, py))
                slip = math.hypot(px - hx, py - hy)
                slip_max = max(slip_max, slip)
            else:  # unloaded or swinging: slip counts from when it supports again
                slip = 0.0
                self._home[f] = (px, py)
            vals += (*qp[i], fz, math.hypot(fx, fy), mx, my, slip)
        csv_row, kept = self._csv_row, self._tau.start
        csv_row[:kept] = vals
        csv_row[self._tau] = command.values
        csv_row[self._q] = state.q
        self.csv.write(csv_row)
        row[:kept] = csv_row[:kept]
        row[x["t_plant"]] = mon.time_s if mon is not None else t
        row[x["stance"]] = stance and not sol.fallback
        row[x["ctrl_us"]] = sol.controller_time_s * 1e6
        row[x["qp_us"]] = sol.qp_time_s * 1e6
        row[x["slip"]] = slip_max
        if mon is not None:
            row[x["physics_us"]] = mon.sim.physics_time_s * 1e6
        self.k = k + 1
        now = time.perf_counter()
        if self._last_cycle_end is not None:
            row[x["cycle_us"]] = (now - self._last_cycle_end) * 1e6
        self._last_cycle_end = now
        self.ctx.progress.advance()
        if k % VALUES_EVERY == 0:
            self.values()
        return mon is not None and mon.fall_reason is not None

    def with_truth(self, com_W: np.ndarray, fell: bool) -> dict[str, Any]:
        """Replace the CoM error and the fall verdict by the plant's truth (a DDS run's truth log).

        Args:
            com_W: The true CoM (k, 3) [m] at each recorded cycle's state.
            fell: Whether the truth log shows the robot fell.
        """
        r = self.record()
        r.com[:] = com_W[: len(r.t)]  # the plant at each state's time: t_plant == t
        self.com_from_truth = True
        err = com_tracking_error(r)
        self.ctx.values.update({"com_error_rms_m": float(np.sqrt(np.mean(np.sum(err**2, axis=1)))),
                                "com_error_source": "truth log", "fell": fell,
                                "fall_reason": "pelvis below its fall height (truth log)" if fell else None})
        return self.ctx.values

    def values(self, sim: Simulator | None = None) -> dict[str, Any]:
        """Fill ``ctx.values`` from the cycles so far (an interrupted run keeps them) and return them."""
        ctx = self.ctx
        if not self.k:
            return ctx.values
        r = self.record()
        com_err = com_tracking_error(r)
        settled = r.t >= r.t[0] + SETTLE_S
        stance = r.stance & settled
        rel = np.abs(r.fz_qp.sum(1) - r.fz_mj.sum(1)) / self.mg
        per_foot = np.abs(r.fz_qp - r.fz_mj) / self.mg
        ctrl, mon = self.wb.controller, self.monitor
        physics_us = self._rows[: self.k, self._extra["physics_us"]]
        overhead = r.cycle_us - r.ctrl_us - physics_us

        def stat(x: np.ndarray, how: str) -> float:
            if not x.size:
                return float("nan")
            return float(np.percentile(x, {"median": 50, "p95": 95, "max": 100}[how]))

        ctx.values.update({
            "fell": mon is not None and mon.fall_reason is not None,
            "fall_reason": mon.fall_reason if mon is not None else None,
            "fall_time_s": mon.fall_time_s if mon is not None else None,
            "controller_fallback_at_s": ctrl.infeasible_at_s,
            "qp_relaxed_cycles": ctrl.relaxed_cycles,
            "com_error_rms_m": float(np.sqrt(np.mean(np.sum(com_err**2, axis=1)))),
            "max_foot_slip_m": float(np.max(r.slip)),
            "contact_force_rel_error": stat(rel[stance], "median"),
            "contact_force_rel_error_p95": stat(rel[stance], "p95"),
            "contact_force_rel_error_max": stat(rel[stance], "max"),
            "contact_force_rel_error_settling_max": stat(rel[~settled], "max"),
            "controller_time_median_us": float(np.median(r.ctrl_us)),
            "qp_solve_time_median_us": stat(r.qp_us[r.qp_us > 0], "median"),
            "cycle_time_median_us": stat(r.cycle_us[np.isfinite(r.cycle_us)], "median"),
            # MuJoCo's step within the cycle (in-process; NaN over DDS, where the plant is the bridge)
            "physics_step_time_median_us": stat(physics_us, "median") if mon is not None else float("nan"),
            # the cycle beyond its controller and its physics step (targets, state, command, plant
            # monitor, this record and its CSV row, the loop), per cycle; in-process only
            "cycle_overhead_median_us": stat(overhead[np.isfinite(overhead)], "median")
            if mon is not None else float("nan"),
            "qp_fast_path_fraction": ctrl.fast_path_cycles / max(1, ctrl.fast_path_cycles + ctrl.daqp_cycles),
            "contact_normal_rel_error_per_foot": {f: stat(per_foot[stance, i], "median")
                                                  for i, f in enumerate(FEET)},
            "pelvis_z_min_m": float(np.min(r.z)),
        })
        if sim is not None:
            ctx.values["torque_saturation_steps"] = int(sim.saturated_commands)
        if ctrl.infeasible_message is not None:
            ctx.values["controller_fallback_reason"] = ctrl.infeasible_message
        return ctx.values
