"""What ``mbctl g1-walk`` records each control cycle: the CSV row, the record, and the report's values.

Each cycle (the control loop's ``on_step``, after the plant ran the command) puts the walking
controller's plan (DCM, its reference, the ZMP reference, the commanded CMP, the gait phase) beside
what MuJoCo did (:class:`~mbctl.sim.monitor.PlantMonitor`: the CoM, each foot's measured normal
force and site, the fall). Foot slip is the horizontal drift of a supporting foot's site from where
it started to support: a stance runs from the first cycle at full contact weight with at least 10 % of
m g measured on the foot to the cycle its contact is released (a brief drop of the measured force in
between does not split it); each stance's largest drift is one slip sample (``max_foot_slip_m`` and
``median_foot_slip_m`` over the stances). The report's values are computed after the loop, also
when the run was interrupted or failed (:meth:`~mbctl.jobs.runner.RunContext.values_at_end`).

Memory is bounded and every figure is over every cycle. The CSV streams every cycle's row; the
plots' rows (:meth:`WalkLog.record`) are every ``stride``-th cycle and the last, at most
``MAX_LOG_ROWS`` (the control loop's cap, :func:`mbctl.control.loop.log_stride`). The RMS, the
extremes and the counts are summed cycle by cycle in plain floats; the medians and 95th percentiles
need every cycle's value, kept as float32 (16 bytes a cycle in-process, 8 over DDS: see
``_QUANTILES``), about 30 MB for an hour's walk.
"""

from __future__ import annotations

import math
from array import array
from typing import Any, NamedTuple

import numpy as np

from mbctl.control.loop import MAX_LOG_ROWS, log_rows, log_stride
from mbctl.control.wbc import WalkingController
from mbctl.jobs.log_sums import nan_max, nan_min
from mbctl.jobs.runner import RunContext
from mbctl.jobs.state_fall import StateFallWatch
from mbctl.robots.conventions import quat_xyzw_yaw
from mbctl.robots.g1 import FEET
from mbctl.robots.interface import RobotState
from mbctl.sim.monitor import PlantMonitor

#: A foot supports (its slip counts) when MuJoCo measures at least this fraction of m g on it.
SUPPORT_FRACTION = 0.1
#: Gait phases as numbers in the CSV.
PHASES = {"start": 0, "single": 1, "double": 2}
#: The CSV's columns before the feet's (each foot adds :data:`FOOT_COLUMNS`).
COLUMNS = ("time_s", "phase", "stance", "cmd_vx_m_s", "cmd_vy_m_s", "cmd_yaw_rate_rad_s", "pelvis_x_m",
           "pelvis_y_m", "pelvis_z_m", "pelvis_yaw_rad", "com_x_m", "com_y_m", "com_z_m", "dcm_x_m",
           "dcm_y_m", "dcm_ref_x_m", "dcm_ref_y_m", "zmp_ref_x_m", "zmp_ref_y_m", "cmp_x_m", "cmp_y_m",
           "zmp_ref_margin_m", "cmp_margin_m", "push_fx_N", "push_fy_N", "controller_us", "qp_us")
FOOT_COLUMNS = ("weight", "fz_qp_N", "fz_mj_N", "x_m", "y_m", "slip_m")
_NAN = float("nan")
#: The per-cycle values kept for the medians and 95th percentiles, float32 each (4 bytes a cycle;
#: 7 significant digits: 1e-4 N of a 100 N force error, 1e-4 us of a 500 us solve). In-process: the
#: contact force error |sum f_z QP - MuJoCo| [N] of a single, of a double support cycle (NaN in
#: the other phases), the controller's and the QP's times [us]; over DDS (no plant forces) the times.
_QUANTILES = ("force_single_N", "force_double_N", "controller_us", "qp_us")
_QUANTILES_DDS = ("controller_us", "qp_us")


class WalkRecord(NamedTuple):
    """The rows kept so far (k: every ``stride``-th cycle and the last), as columns; feet in FEET order.

    Attributes:
        columns: Column name -> (k,) values (the CSV's).
        foot: Foot name -> column stem -> (k,) values (``fz_qp_N``, ``fz_mj_N``, ``slip_m``...).
    """

    columns: dict[str, np.ndarray]
    foot: dict[str, dict[str, np.ndarray]]


def _stat(x: np.ndarray, largest: float) -> dict[str, float | None]:
    """Median and 95th percentile of the finite ``x``, and ``largest``; None for no samples.

    ``largest`` is the same values' maximum, taken each cycle in float64 (``x`` is float32).
    """
    x = x[np.isfinite(x)]
    if not x.size:
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(x)), "p95": float(np.percentile(x, 95)), "max": largest}


class WalkLog:
    """Records a g1-walk run into ``n`` preallocated rows, streams the CSV, computes the report's values.

    Args:
        ctx: The run.
        walker: The walking controller.
        monitor: The plant's measurements (None over DDS).
        pushes: The pushes on the plant (:class:`~mbctl.jobs.g1_walk_push.PhasePushes`, or None): armed
            and scored here each cycle.
        n: Cycles of the run (the arrays are preallocated for them).
        mg_n: The plant's weight m g [N].
    """

    def __init__(self, ctx: RunContext, walker: WalkingController, monitor: PlantMonitor | None,
                 pushes: Any, n: int, mg_n: float):
        self.ctx, self.walker, self.monitor, self.pushes, self.mg = ctx, walker, monitor, pushes, mg_n
        ctx.values_at_end(self.values)  # an interrupted or failed run's figures, after the loop
        header = [*COLUMNS, *(f"{f}_{c}" for f in FEET for c in FOOT_COLUMNS)]
        self.csv = ctx.open_csv(header)
        self._col = {name: i for i, name in enumerate(header)}
        # each foot's contact group and site in the monitor's arrays
        self._group = {f: monitor.group_names.index(f) for f in FEET} if monitor is not None else {}
        self._site = {f: monitor.site_names.index(f) for f in FEET} if monitor is not None else {}
        # the plots' rows: every stride-th cycle and the last; a cycle not kept is written to the next
        # kept row's place and overwritten (as the control loop's log), so the run's last is kept
        self.n, self.stride = n, log_stride(n, MAX_LOG_ROWS)
        self._rows = np.full((log_rows(n, self.stride), len(header)), np.nan)
        self._row = 0
        names = _QUANTILES if monitor is not None else _QUANTILES_DDS
        self._quantiles = np.zeros((n, len(names)), dtype=np.float32)  # every cycle's (_QUANTILES)
        # every cycle's sums and extremes: the first and last time [s], the DCM error's sum of squares
        # [m^2] and largest [m], the smallest ZMP reference margin while walking and CMP margin [m],
        # the cycles the CMP was clamped, the largest force error in single and double support [N]
        self._t0 = self._t1 = _NAN
        self._dcm_sq, self._dcm_max = 0.0, -math.inf
        self._zmp_min, self._walking, self._cmp_min, self._clamped = math.inf, False, math.inf, 0
        self._force_max = {1: -math.inf, 2: -math.inf}
        self.k = 0
        #: Over DDS (no monitor), the fall rule on the estimated state: it ends the run.
        self.state_fall = StateFallWatch()
        self._home: dict[str, tuple[float, float] | None] = dict.fromkeys(FEET)
        self._stance_slip = dict.fromkeys(FEET, 0.0)
        #: Each stance's largest slip [m], in the order they ended (the open ones added in values()).
        self.stance_slips: list[float] = []
        #: Where the feet stood and were put down: (time [s], foot, x [m], y [m], yaw [rad]) in W.
        self.footprints: list[tuple[float, str, float, float, float]] = []
        #: Steps whose footstep the step adaptation moved (the DCM left its tube in their swing), and
        #: those a step limit held short.
        self.adaptations = {"steps_adapted": 0, "steps_limited": 0}
        self._adapt_us = array("f")  # the step adaptation's solve times [us], float32, when it ran
        self._swing: tuple[int, bool, bool] = (-1, False, False)  # (swing number, adapted, limited)

    @property
    def rows(self) -> int:
        """Rows kept so far (every ``stride``-th cycle and the last)."""
        return log_rows(self.k, self.stride)

    def record(self) -> WalkRecord:
        """The kept rows so far, by column (views): every cycle when ``stride`` is 1."""
        rows = self._rows[: self.rows]
        cols = {name: rows[:, i] for name, i in self._col.items()}
        feet = {f: {c: cols[f"{f}_{c}"] for c in FOOT_COLUMNS} for f in FEET}
        return WalkRecord(cols, feet)

    def on_step(self, k: int, state: RobotState, reference: object, command: object) -> bool:
        """Record cycle ``k`` (the loop's ``on_step``); True once the robot has fallen (ends the run)."""
        w, mon, c = self.walker, self.monitor, self._col
        s, sol = w.status, w.wbc.solution
        row = self._rows[self._row]
        q = state.q
        yaw = quat_xyzw_yaw(q[3:7])
        com = mon.com_W if mon is not None else w.wbc.state.com()
        t, phase = state.time_s, PHASES[s.phase]
        (dx, dy), (rx, ry) = s.dcm.tolist(), s.dcm_ref.tolist()
        row[: c["push_fx_N"]] = (t, phase, 0 if s.stance == "both" else
                                 1 + FEET.index(s.stance), *w.velocity, q[0], q[1], q[2], yaw, *com, dx, dy,
                                 rx, ry, *s.zmp_ref, *s.cmp_clamped, s.zmp_ref_margin_m, s.cmp_margin_m)
        if self.pushes is not None:
            row[c["push_fx_N"]:c["push_fx_N"] + 2] = self.pushes.force_W[:2]
        # the walking controller's whole cycle (footsteps, DCM plan, tasks and the whole-body QP
        # layer), not the QP layer's alone (sol.controller_time_s: about half of it)
        ctrl_us, qp_us = w.compute_time_s * 1e6, sol.qp_time_s * 1e6
        row[c["controller_us"]] = ctrl_us
        row[c["qp_us"]] = qp_us
        force_err = 0.0  # sum over the feet of f_z QP - MuJoCo [N]
        # (plain floats by index: the solution's and the monitor's dicts of arrays cost ~20 us a cycle)
        fz_qp_of = dict(zip(sol.force_slices, sol.normal_forces_W, strict=True))
        if mon is not None:
            sums, sites = mon.contact_sums, mon.site_array_W
        for f in FEET:
            cs = w.wbc.contacts[f]
            fz_qp = fz_qp_of[f]
            i = c[f"{f}_weight"]
            if mon is None:
                row[i:i + 6] = (cs.weight, fz_qp, _NAN, _NAN, _NAN, _NAN)
                continue
            fz = sums[self._group[f]][2]  # MuJoCo's normal force [N] (the group's sums: fx, fy, fz, ...)
            x, y, _ = sites[self._site[f]].tolist()
            held = cs.active and cs.weight == 1.0
            slip = self._slip(f, held, fz >= SUPPORT_FRACTION * self.mg, x, y)
            row[i:i + 6] = (cs.weight, fz_qp, fz, x, y, slip)
            force_err += fz_qp - fz
        self._sums(k, t, phase, math.hypot(dx - rx, dy - ry), s.zmp_ref_margin_m, s.cmp_margin_m)
        if mon is None:
            self._quantiles[k] = (ctrl_us, qp_us)
        else:
            err = abs(force_err)
            if phase and math.isfinite(err):
                self._force_max[phase] = max(self._force_max[phase], err)
            self._quantiles[k] = (err if phase == 1 else _NAN, err if phase == 2 else _NAN, ctrl_us, qp_us)
        self._adaptation(s.adaptation)
        self._footprints(state.time_s)
        self.csv.write(row)
        if k % self.stride == 0:
            self._row += 1
        self.k = k + 1
        fallen = mon.fall_reason is not None if mon is not None else self.state_fall.check(state)
        if self.pushes is not None and mon is not None:
            self.pushes.on_cycle(state.time_s, mon.sim.time_s, fallen)
        self.ctx.progress.advance()
        return fallen

    def _sums(self, k: int, t: float, phase: int, dcm_err: float, zmp_margin: float,
              cmp_margin: float) -> None:
        """Every cycle's sums and extremes: time [s], DCM error [m], ZMP reference and CMP margins [m]."""
        if not k:
            self._t0 = t
        self._t1 = t
        self._dcm_sq += dcm_err * dcm_err
        self._dcm_max = nan_max(self._dcm_max, dcm_err)
        if phase:
            self._walking = True
            self._zmp_min = nan_min(self._zmp_min, zmp_margin)
        self._cmp_min = nan_min(self._cmp_min, cmp_margin)
        if cmp_margin < self.walker.config.cmp_margin_m - 1e-9:
            self._clamped += 1

    def _footprints(self, t: float) -> None:
        """Both feet where they stand at the first cycle; then each foot where it touched down."""
        gait, event = self.walker.gait, self.walker.status.event
        if gait is None:
            return
        if not self.footprints:
            feet: tuple[str, ...] = FEET
        elif event is not None and event.kind == "touchdown":
            feet = (event.foot,)
        else:
            return
        for f in feet:
            step = gait.placed[f]
            self.footprints.append((t, f, *step.position[:2].tolist(), step.yaw_rad))

    def _slip(self, foot: str, held: bool, loaded: bool, x: float, y: float) -> float:
        """This cycle's slip of ``foot`` [m]; a stance's largest is kept when its contact is released.

        Args:
            foot: The foot.
            held: Its contact is in force at full weight.
            loaded: MuJoCo measures at least 10 % of m g on it.
            x: Its site's x [m] in W.
            y: Its site's y [m] in W.
        """
        home = self._home[foot]
        if not held:
            if home is not None:
                self.stance_slips.append(self._stance_slip[foot])
            self._home[foot], self._stance_slip[foot] = None, 0.0
            return 0.0
        if home is None:
            if not loaded:
                return 0.0
            self._home[foot] = home = (x, y)
        slip = math.hypot(x - home[0], y - home[1])
        self._stance_slip[foot] = max(self._stance_slip[foot], slip)
        return slip

    def _adaptation(self, adaptation: Any) -> None:
        """Count the steps the adaptation moved (once per swing) and time its QP solves."""
        gait = self.walker.gait
        if adaptation is None or gait is None or gait.swing is None or not adaptation.outside_tube:
            return
        self._adapt_us.append(adaptation.solve_time_s * 1e6)
        swing, adapted, limited = self._swing
        if swing != gait.steps:
            swing, adapted, limited = gait.steps, False, False
        if not adapted:
            self.adaptations["steps_adapted"] += 1
        if adaptation.limited and not limited:
            self.adaptations["steps_limited"] += 1
        self._swing = (swing, True, limited or adaptation.limited)

    def values(self) -> dict[str, Any]:
        """Fill ``ctx.values`` from the cycles so far and return them."""
        ctx, w, mon = self.ctx, self.walker, self.monitor
        if not self.k:
            return ctx.values
        k, q = self.k, self._quantiles[: self.k]
        ctrl_us, qp_us = q[:, -2], q[:, -1]
        observed = mon is not None
        slips = np.array(self.stance_slips + [v for f, v in self._stance_slip.items() if self._home[f]])
        force_err = {}
        if observed:
            for name, code in (("single", 1), ("double", 2)):
                stats = _stat(q[:, code - 1], self._force_max[code])
                rel = {f"{k}_rel_mg": None if v is None else v / self.mg for k, v in stats.items()}
                force_err[name] = {**{f"{k}_N": v for k, v in stats.items()}, **rel}
        gait = w.gait
        ctx.values.update({
            **self.state_fall.values(mon),
            "controller_fallback_at_s": w.wbc.infeasible_at_s,
            "qp_relaxed_cycles": w.wbc.relaxed_cycles,
            "controller_fallback_reason": w.wbc.infeasible_message,
            "steps": w.steps,
            "touchdowns": dict(gait.touchdowns) if gait is not None else {},
            "max_foot_slip_m": float(slips.max()) if observed and slips.size else None,
            "median_foot_slip_m": float(np.median(slips)) if observed and slips.size else None,
            "min_zmp_margin_m": float(self._zmp_min) if self._walking else None,
            "min_cmp_margin_m": float(self._cmp_min),
            "cmp_clamped_fraction": self._clamped / k,
            "dcm_rms_m": math.sqrt(self._dcm_sq / k),
            "dcm_max_error_m": self._dcm_max,
            "contact_force_error": force_err if observed else None,
            "step_adaptations": dict(self.adaptations),
            "step_adaptation_qp_median_us": float(np.median(np.frombuffer(self._adapt_us, np.float32)))
            if self._adapt_us else None,
            "controller_time_median_us": float(np.median(ctrl_us)),
            "qp_solve_time_median_us": float(np.median(qp_us[qp_us > 0])) if (qp_us > 0).any() else None,
            "walk_time_s": self._t1 - self._t0,
        })
        return ctx.values
