"""What ``mbctl g1-wbc`` records each control cycle: the CSV row, the logs, and the report's values.

Each cycle (the control loop's ``on_step``, after the plant ran the command) puts side by side
what the QP predicted and what MuJoCo did (:class:`~mbctl.sim.monitor.PlantMonitor`): per foot the
normal and tangential force and the centre of pressure, the CoM against its reference, and the
slip of each supporting foot. The report's values are computed after the loop, also when the run
was interrupted or failed (:meth:`~mbctl.jobs.runner.RunContext.values_at_end`), never during it:
a refresh over a long run's cycles (about 25 ms a median at an hour's 1.8 million) would stall it.

Memory is bounded and every figure is over every cycle. The CSV streams every cycle's row. The
plots' rows (:meth:`WBCLog.record`) are every ``stride``-th cycle and the last, at most
``MAX_LOG_ROWS`` (the control loop's cap, :func:`mbctl.control.loop.log_stride`). The RMS, the
largest and smallest values are summed cycle by cycle (:class:`CoMErrorSums`, ``_Extremes``); the
medians and 95th percentiles need every cycle's value, kept as float32 (32 bytes a cycle
in-process, 36 over DDS: see ``_QUANTILES``), so a run of an hour keeps about 60 MB.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any, NamedTuple

import numpy as np

from mbctl.control.loop import MAX_LOG_ROWS, kept_cycles, log_rows, log_stride
from mbctl.control.wbc import Standing, WBCSolution
from mbctl.jobs.log_sums import CoMErrorSums, nan_max, nan_min, quantile
from mbctl.jobs.runner import RunContext
from mbctl.robots.commands import Command
from mbctl.robots.g1 import FEET
from mbctl.robots.interface import RobotState
from mbctl.sim.monitor import PlantMonitor, PlantSample
from mbctl.sim.perturb import PushSchedule
from mbctl.sim.simulator import Simulator

#: A foot supports the robot (its slip counts) when MuJoCo measures at least this fraction of
#: m g on it at full contact weight.
SUPPORT_FRACTION = 0.1

#: The first period [s] of a run, while MuJoCo's soft contacts settle from the set start pose
#: (about 80 N more than m g on the first step, decaying over ~20 ms): left out of the force-error
#: statistics and reported on its own (``contact_force_rel_error_settling_max``).
SETTLE_S = 0.05

#: A foot's columns in the CSV (QP fz, ft, CoP x, y; MuJoCo's the same; slip).
_PER_FOOT = 9
#: A foot's MuJoCo columns and slip when the plant is not observed (over DDS).
_NO_PLANT = (float("nan"),) * 5
_NO_PUSH = (0.0, 0.0)
#: Cycles :meth:`WBCLog.on_step` keeps before recording them (about 25 ms of the G1 job's wall time).
BATCH = 64
#: What each kept row holds after the CSV's columns (the record's other fields, and the CoM error
#: of the last plant sample compared: its plant time [s] and norm [m]).
_EXTRA = ("t_plant", "stance", "ctrl_us", "qp_us", "slip", "cycle_us", "physics_us", "com_err_t", "com_err_m")
#: The per-cycle values kept for the medians and 95th percentiles, float32 each (4 bytes a cycle;
#: a float32 keeps 7 significant digits: 0.03 ns of a 500 us cycle, 1e-7 of a force error). In-process
#: (32 bytes a cycle): the cycle counts in the contact-force statistics (stance, settled, QP not in
#: fallback: 1, else 0), |sum f_z QP - MuJoCo| / m g, each foot's |f_z QP - MuJoCo| / m g, the
#: controller's, QP's, whole cycle's and physics step's times [us]. Over DDS the plant's forces and
#: physics step are not observed: the three times alone (12 bytes, and the CoM reference's 24 bytes
#: a cycle for :meth:`WBCLog.with_truth`).
_QUANTILES = ("stance", "rel", *(f"{f}_rel" for f in FEET), "ctrl_us", "qp_us", "cycle_us", "physics_us")
_QUANTILES_DDS = ("ctrl_us", "qp_us", "cycle_us")


class WBCRecord(NamedTuple):
    """Rows of a g1-wbc run (k of them), feet in :data:`~mbctl.robots.g1.FEET` order.

    From :meth:`WBCLog.record`: the kept rows (every ``stride``-th cycle and the last).

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


def _mean(x: np.ndarray) -> float:
    """The mean of ``x`` (NaN when empty)."""
    return float(np.mean(x)) if x.size else float("nan")


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
    """Records a g1-wbc run cycle by cycle: the CSV, kept rows, every cycle's sums and quantile inputs.

    Args:
        ctx: The run.
        wb: The standing controller.
        monitor: The plant's measurements (None over DDS).
        pushes: The pushes on the plant, or None.
        n: Cycles of the run (the arrays are preallocated for them).
        mg_n: The plant's weight m g [N].
        q_names: The CSV's columns of q.
    """

    def __init__(self, ctx: RunContext, wb: Standing, monitor: PlantMonitor | None,
                 pushes: PushSchedule | None, n: int, mg_n: float, q_names: list[str]):
        self.ctx, self.wb, self.monitor, self.pushes, self.mg = ctx, wb, monitor, pushes, mg_n
        ctx.values_at_end(self.values)  # an interrupted or failed run's figures, after the loop
        ctrl = wb.controller
        header = ["time_s", "com_ref_x_m", "com_ref_y_m", "com_ref_z_m", "com_x_m", "com_y_m", "com_z_m",
                  "base_z_m", "push_fx_N", "push_fy_N"]
        for f in FEET:
            header += [f"{f}_fz_qp_N", f"{f}_ft_qp_N", f"{f}_cop_x_qp_m", f"{f}_cop_y_qp_m",
                       f"{f}_fz_mj_N", f"{f}_ft_mj_N", f"{f}_cop_x_mj_m", f"{f}_cop_y_mj_m", f"{f}_slip_m"]
        header += [f"tau_{a}_N_m" for a in ctrl.joints.actuators] + q_names
        self.csv = ctx.open_csv(header)
        # The kept rows (every stride-th cycle and the last, for the plots): the CSV's columns up to
        # the torques, then what only the record keeps; the record's fields are views. The torques and
        # q go to the CSV only (a scratch row). A cycle not kept is written to the next kept row's
        # place and overwritten, as the control loop's log does: the run's last cycle is always kept.
        w, nf, nt = len(header), len(FEET), len(ctrl.joints.actuators)
        feet_at = header.index(f"{FEET[0]}_fz_qp_N")
        self._tau = slice(feet_at + _PER_FOOT * nf, feet_at + _PER_FOOT * nf + nt)
        self._q = slice(self._tau.stop, w)
        self._csv_row = np.zeros(w)
        kept = self._tau.start
        self.n, self.stride = n, log_stride(n, MAX_LOG_ROWS)
        rows = log_rows(n, self.stride)
        self._rows = np.zeros((rows, kept + len(_EXTRA)))
        self._extra = {name: kept + i for i, name in enumerate(_EXTRA)}
        self._rows[:, self._extra["cycle_us"]] = np.nan  # the first cycle has no start
        self._feet = self._rows[:, feet_at:feet_at + _PER_FOOT * nf].reshape(rows, nf, _PER_FOOT)
        self._row = 0  # the kept row this cycle goes to
        # every cycle's values for the medians and 95th percentiles (_QUANTILES), one store a cycle
        names = _QUANTILES if monitor is not None else _QUANTILES_DDS
        self._qcol = {name: i for i, name in enumerate(names)}
        self._quantiles = np.zeros((n, len(names)), dtype=np.float32)
        # over DDS, every cycle's CoM reference (n, 3) [m] (24 bytes a cycle): with_truth compares the
        # truth log's CoM with it after the run (in-process the error is summed as the run goes)
        self._com_ref = np.zeros((n, 3)) if monitor is None else np.zeros((0, 3))
        self.com_sums = CoMErrorSums()
        # every cycle's extremes: largest slip, rel. force error in and out of the settling period,
        # lowest pelvis [m]; the first cycle's time [s] (the settling period's start)
        self._slip_max, self._rel_max, self._settling_max = 0.0, -math.inf, -math.inf
        self._z_min = math.inf
        self._t0 = math.nan
        self.k = 0
        self.com_from_truth = False  # with_truth replaced the estimated CoM by the plant's
        self._last_cycle_end: float | None = None
        self._pending: deque[tuple] = deque()  # cycles kept by on_step, not yet recorded
        self._foot_states = [ctrl.contacts[f] for f in FEET]
        self._home: dict[str, tuple[float, float]] = {}  # where each foot started to support
        self._points_src: object = None  # the solution's contact points, as lists per foot (_qp_feet)
        self._points: dict[str, list[list[float]]] = {}
        if monitor is not None:  # FEET's places among the monitor's contact groups and sites
            self._groups = [monitor.group_names.index(f) for f in FEET]
            self._sites = [monitor.site_names.index(f) for f in FEET]

    @property
    def rows(self) -> int:
        """Rows kept so far (every ``stride``-th cycle and the last)."""
        self._drain()
        return log_rows(self.k, self.stride)

    def row_cycles(self) -> np.ndarray:
        """The cycle of each kept row (R,)."""
        self._drain()
        return kept_cycles(self.k, self.stride)

    def record(self) -> WBCRecord:
        """The kept rows so far (views, but ``stance``, a bool copy): every cycle when ``stride`` is 1."""
        rows, feet, x = self._rows[: self.rows], self._feet[: self.rows], self._extra
        return WBCRecord(rows[:, 0], rows[:, x["t_plant"]], rows[:, 1:4], rows[:, 4:7],
                         feet[:, :, 0], feet[:, :, 4], feet[:, :, 1], feet[:, :, 5], feet[:, :, 2:4],
                         feet[:, :, 6:8], rows[:, x["stance"]] > 0.5, rows[:, x["slip"]], rows[:, 7],
                         rows[:, x["ctrl_us"]], rows[:, x["qp_us"]], rows[:, x["cycle_us"]])

    def com_error_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """For each kept row, the last plant sample compared with the reference: its time [s], |error| [m].

        NaN where none was yet (the first cycles behind a link's latency).
        """
        rows, x = self._rows[: self.rows], self._extra
        return rows[:, x["com_err_t"]], rows[:, x["com_err_m"]]

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
        """Keep cycle ``k`` to record (the loop's ``on_step``); True once the robot has fallen (ends the run).

        A cycle's inputs are kept as they are (the state, command and solution are the cycle's own
        objects; the plant's sample is immutable) and recorded :data:`BATCH` cycles at a time, and by
        every reader (:meth:`record`, :meth:`values`): the recording's Python work runs in one tight
        loop, not between a physics step and a solve that evict it from the CPU's caches (about 2.5x
        its cost there).
        """
        now = time.perf_counter()
        ctrl, mon = self.wb.controller, self.monitor
        left, right = self._foot_states
        self._pending.append((
            k, state, command, ctrl.last, self.wb.com.target,
            self.pushes.force_W[:2].tolist() if self.pushes is not None else _NO_PUSH,
            ((left.active, left.weight), (right.active, right.weight)),
            mon.sample if mon is not None else ctrl.state.com().tolist(), now))
        if len(self._pending) >= BATCH:
            self._drain()
        return mon is not None and mon.fall_reason is not None

    def _drain(self) -> None:
        """Record the cycles kept so far, in order (the progress bar advances by them)."""
        pending, record = self._pending, self._record
        if pending:
            self.ctx.progress.advance(len(pending))
        while pending:
            record(*pending.popleft())

    def _record(self, k: int, state: RobotState, command: Command, sol: WBCSolution, ref_W: np.ndarray,
                push: tuple[float, float], feet: list[tuple[bool, float]], plant: PlantSample | list[float],
                now: float) -> None:
        """Record cycle ``k`` from what :meth:`on_step` kept.

        ``plant`` is the monitor's sample of the period, or over DDS the controller's CoM (3 floats).
        """
        mon = self.monitor
        row, x = self._rows[self._row], self._extra
        t = state.time_s
        if not k:
            self._t0 = t
        # the row's first columns built as one list and stored in one assignment (a numpy store per
        # value or slice costs more than the values' arithmetic)
        # the plant's CoM in-process; over DDS the controller's (from the estimated state), replaced
        # by the bridge's truth after the run when given (with_truth)
        com = plant.com_W.tolist() if mon is not None else plant  # type: ignore[union-attr]
        ref = ref_W.tolist()
        z = float(state.q[2])
        vals = [t, *ref, *com, z, *push]
        stance = True
        slip_max = 0.0
        qp = self._qp_feet(sol)
        fz_mj: list[float] = []
        if mon is not None:  # the monitor's groups and sites in FEET order, as plain numbers
            sums = mon.sums_of(plant)  # type: ignore[arg-type]
            xyz = plant.site_array_W.tolist()  # type: ignore[union-attr]
        for i, f in enumerate(FEET):
            active, weight = feet[i]
            supporting = active and weight == 1.0
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
            fz_mj.append(fz)
            vals += (*qp[i], fz, math.hypot(fx, fy), mx, my, slip)
        csv_row, kept = self._csv_row, self._tau.start
        csv_row[:kept] = vals
        csv_row[self._tau] = command.values
        csv_row[self._q] = state.q
        self.csv.write(csv_row)
        row[:kept] = csv_row[:kept]
        t_plant = plant.time_s if mon is not None else t  # type: ignore[union-attr]
        stance = stance and not sol.fallback
        ctrl_us, qp_us = sol.controller_time_s * 1e6, sol.qp_time_s * 1e6
        row[x["t_plant"]] = t_plant
        row[x["stance"]] = stance
        row[x["ctrl_us"]] = ctrl_us
        row[x["qp_us"]] = qp_us
        row[x["slip"]] = slip_max
        # every cycle's sums and extremes (plain floats)
        self._slip_max = nan_max(self._slip_max, slip_max)
        self._z_min = nan_min(self._z_min, z)
        if mon is None:
            self._com_ref[k] = ref
        sums_ = self.com_sums
        sums_.add(t, ref, t_plant, com)  # type: ignore[arg-type]  # 3 floats each
        row[x["com_err_t"]], row[x["com_err_m"]] = sums_.last
        self.k = k + 1
        cycle_us = math.nan
        if self._last_cycle_end is not None:
            cycle_us = (now - self._last_cycle_end) * 1e6
            row[x["cycle_us"]] = cycle_us
        self._last_cycle_end = now
        if mon is None:
            self._quantiles[k] = (ctrl_us, qp_us, cycle_us)
        else:
            physics_us = plant.physics_time_s * 1e6  # type: ignore[union-attr]
            row[x["physics_us"]] = physics_us
            mg = self.mg
            rel = abs((qp[0][0] + qp[1][0]) - (fz_mj[0] + fz_mj[1])) / mg
            if t >= self._t0 + SETTLE_S:
                counted = stance
                if counted:
                    self._rel_max = nan_max(self._rel_max, rel)
            else:
                counted = False
                self._settling_max = nan_max(self._settling_max, rel)
            self._quantiles[k] = (counted, rel, abs(qp[0][0] - fz_mj[0]) / mg, abs(qp[1][0] - fz_mj[1]) / mg,
                                  ctrl_us, qp_us, cycle_us, physics_us)
        if k % self.stride == 0:
            self._row += 1

    def with_truth(self, com_W: np.ndarray, fell: bool) -> dict[str, Any]:
        """Replace the CoM error and the fall verdict by the plant's truth (a DDS run's truth log).

        Args:
            com_W: The true CoM (k, 3) [m] at each recorded cycle's state.
            fell: Whether the truth log shows the robot fell.

        Raises:
            ValueError: An in-process run (its CoM is the plant's already; no reference kept per cycle).
        """
        if self.monitor is not None:
            raise ValueError("with_truth is for a run over DDS: in-process the CoM is the plant's already")
        self._drain()
        k = self.k
        err = com_W[:k] - self._com_ref[:k]  # the plant at each state's time: t_plant == t
        self.com_from_truth = True
        r, cycles = self.record(), self.row_cycles()
        r.com[:] = com_W[cycles]  # the plots' rows
        t_err, err_m = self.com_error_rows()
        t_err[:] = r.t
        err_m[:] = np.linalg.norm(err[cycles], axis=1)
        self.ctx.values.update({"com_error_rms_m": float(np.sqrt(np.mean(np.sum(err**2, axis=1)))),
                                "com_error_source": "truth log", "fell": fell,
                                "fall_reason": "pelvis below its fall height (truth log)" if fell else None})
        return self.ctx.values

    def values(self, sim: Simulator | None = None) -> dict[str, Any]:
        """Fill ``ctx.values`` from every cycle so far (an interrupted run keeps them) and return them."""
        ctx = self.ctx
        self._drain()
        if not self.k:
            return ctx.values
        ctrl, mon, c = self.wb.controller, self.monitor, self._qcol
        q = self._quantiles[: self.k]
        ctrl_us, qp_us, cycle_us = q[:, c["ctrl_us"]], q[:, c["qp_us"]], q[:, c["cycle_us"]]
        nan = float("nan")
        if mon is not None:
            counted = q[:, c["stance"]] > 0.5
            rel = q[counted, c["rel"]]
            physics_us = q[:, c["physics_us"]]
            overhead = cycle_us.astype(float) - ctrl_us - physics_us
            per_foot = {f: quantile(q[counted, c[f"{f}_rel"]]) for f in FEET}
        else:
            rel = np.full(0, nan, dtype=np.float32)
            per_foot = dict.fromkeys(FEET, nan)
        com = self.com_sums
        ctx.values.update({
            "fell": mon is not None and mon.fall_reason is not None,
            "fall_reason": mon.fall_reason if mon is not None else None,
            "fall_time_s": mon.fall_time_s if mon is not None else None,
            "controller_fallback_at_s": ctrl.infeasible_at_s,
            "qp_relaxed_cycles": ctrl.relaxed_cycles,
            # over DDS the estimated CoM's (with_truth replaces it by the truth log's)
            "com_error_rms_m": com.rms(),
            "max_foot_slip_m": self._slip_max,
            "contact_force_rel_error": quantile(rel) if mon is not None else nan,
            "contact_force_rel_error_p95": quantile(rel, "p95") if mon is not None else nan,
            "contact_force_rel_error_max": self._rel_max if mon is not None and rel.size else nan,
            "contact_force_rel_error_settling_max": self._settling_max
            if mon is not None and self._settling_max > -math.inf else nan,
            "controller_time_median_us": float(np.median(ctrl_us)),
            "qp_solve_time_median_us": quantile(qp_us[qp_us > 0]),
            "cycle_time_median_us": quantile(cycle_us[np.isfinite(cycle_us)]),
            # MuJoCo's step within the cycle (in-process; NaN over DDS, where the plant is the bridge)
            "physics_step_time_median_us": quantile(physics_us) if mon is not None else nan,
            # the cycle beyond its controller and its physics step (targets, state, command, plant
            # monitor, this record and its CSV row, the loop), per cycle; in-process only
            "cycle_overhead_median_us": quantile(overhead[np.isfinite(overhead)]) if mon is not None else nan,
            # its mean: the recording's batches (BATCH cycles at once) and the CSV's flushes included
            "cycle_overhead_mean_us": _mean(overhead[np.isfinite(overhead)]) if mon is not None else nan,
            "qp_fast_path_fraction": ctrl.fast_path_cycles / max(1, ctrl.fast_path_cycles + ctrl.daqp_cycles),
            "contact_normal_rel_error_per_foot": per_foot,
            "pelvis_z_min_m": self._z_min,
        })
        if com.unordered:
            ctx.values["com_error_note"] = ("a plant sample came before a reference time already passed: the "
                                            "CoM error is not computed (NaN)")
        if sim is not None:
            ctx.values["torque_saturation_steps"] = int(sim.saturated_commands)
        if ctrl.infeasible_message is not None:
            ctx.values["controller_fallback_reason"] = ctrl.infeasible_message
        return ctx.values
