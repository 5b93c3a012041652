"""What ``mbctl g1-walk`` records each control cycle: the CSV row, the record, and the report's values.

Each cycle (the control loop's ``on_step``, after the plant ran the command) puts the walking
controller's plan (DCM, its reference, the ZMP reference, the commanded CMP, the gait phase) beside
what MuJoCo did (:class:`~mbctl.sim.monitor.PlantMonitor`: the CoM, each foot's measured normal
force and site, the fall). Foot slip is the horizontal drift of a supporting foot's site from where
it started to support: a stance runs from the first cycle at full contact weight with at least 10 % of
m g measured on the foot to the cycle its contact is released (a brief drop of the measured force in
between does not split it); each stance's largest drift is one slip sample (``max_foot_slip_m`` and
``median_foot_slip_m`` over the stances). Rows are
preallocated; the report's values are refreshed every :data:`VALUES_EVERY` cycles.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from mbctl.control.wbc import WalkingController
from mbctl.jobs.runner import RunContext
from mbctl.robots.g1 import FEET
from mbctl.robots.interface import RobotState
from mbctl.sim.monitor import PlantMonitor

#: A foot supports (its slip counts) when MuJoCo measures at least this fraction of m g on it.
SUPPORT_FRACTION = 0.1
#: Cycles between refreshes of the report's values (1 s at 500 Hz).
VALUES_EVERY = 500
#: Gait phases as numbers in the CSV.
PHASES = {"start": 0, "single": 1, "double": 2}
#: The CSV's columns before the feet's (each foot adds :data:`FOOT_COLUMNS`).
COLUMNS = ("time_s", "phase", "stance", "cmd_vx_m_s", "cmd_vy_m_s", "cmd_yaw_rate_rad_s", "pelvis_x_m",
           "pelvis_y_m", "pelvis_z_m", "pelvis_yaw_rad", "com_x_m", "com_y_m", "com_z_m", "dcm_x_m",
           "dcm_y_m", "dcm_ref_x_m", "dcm_ref_y_m", "zmp_ref_x_m", "zmp_ref_y_m", "cmp_x_m", "cmp_y_m",
           "zmp_ref_margin_m", "cmp_margin_m", "push_fx_N", "push_fy_N", "controller_us", "qp_us")
FOOT_COLUMNS = ("weight", "fz_qp_N", "fz_mj_N", "x_m", "y_m", "slip_m")
_NAN = float("nan")


class WalkRecord(NamedTuple):
    """The cycles recorded so far (k), as columns; feet in :data:`~mbctl.robots.g1.FEET` order.

    Attributes:
        columns: Column name -> (k,) values (the CSV's).
        foot: Foot name -> column stem -> (k,) values (``fz_qp_N``, ``fz_mj_N``, ``slip_m``...).
    """

    columns: dict[str, np.ndarray]
    foot: dict[str, dict[str, np.ndarray]]


def _stat(x: np.ndarray) -> dict[str, float | None]:
    """Median, 95th percentile and maximum (None for no samples)."""
    x = x[np.isfinite(x)]
    if not x.size:
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(x)), "p95": float(np.percentile(x, 95)), "max": float(x.max())}


class WalkLog:
    """Records a g1-walk run into ``n`` preallocated rows, streams the CSV, computes the report's values.

    Args:
        ctx: The run.
        walker: The walking controller.
        monitor: The plant's measurements (None over DDS).
        pushes: The pushes on the plant (:class:`~mbctl.jobs.g1_walk_push.PhasePushes`, or None): armed
            and scored here each cycle.
        n: Cycles.
        mg_n: The plant's weight m g [N].
    """

    def __init__(self, ctx: RunContext, walker: WalkingController, monitor: PlantMonitor | None,
                 pushes: Any, n: int, mg_n: float):
        self.ctx, self.walker, self.monitor, self.pushes, self.mg = ctx, walker, monitor, pushes, mg_n
        header = [*COLUMNS, *(f"{f}_{c}" for f in FEET for c in FOOT_COLUMNS)]
        self.csv = ctx.open_csv(header)
        self._col = {name: i for i, name in enumerate(header)}
        self._rows = np.full((n, len(header)), np.nan)
        self.k = 0
        self._home: dict[str, tuple[float, float] | None] = dict.fromkeys(FEET)
        self._stance_slip = dict.fromkeys(FEET, 0.0)
        #: Each stance's largest slip [m], in the order they ended (the open ones added in values()).
        self.stance_slips: list[float] = []
        #: Where the feet stood and were put down: (time [s], foot, x [m], y [m], yaw [rad]) in W.
        self.footprints: list[tuple[float, str, float, float, float]] = []
        #: Steps whose footstep the step adaptation moved (the DCM left its tube in their swing), and
        #: those a step limit held short.
        self.adaptations = {"steps_adapted": 0, "steps_limited": 0}
        self._adapt_us: list[float] = []
        self._swing: tuple[int, bool, bool] = (-1, False, False)  # (swing number, adapted, limited)

    def record(self) -> WalkRecord:
        """The cycles so far, by column (views)."""
        rows = self._rows[: self.k]
        cols = {name: rows[:, i] for name, i in self._col.items()}
        feet = {f: {c: cols[f"{f}_{c}"] for c in FOOT_COLUMNS} for f in FEET}
        return WalkRecord(cols, feet)

    def on_step(self, k: int, state: RobotState, reference: object, command: object) -> bool:
        """Record cycle ``k`` (the loop's ``on_step``); True once the robot has fallen (ends the run)."""
        w, mon, c = self.walker, self.monitor, self._col
        s, sol = w.status, w.wbc.solution
        row = self._rows[k]
        q = state.q
        yaw = math.atan2(2.0 * (q[6] * q[5] + q[3] * q[4]), 1.0 - 2.0 * (q[4] ** 2 + q[5] ** 2))
        com = mon.com_W if mon is not None else w.wbc.state.com()
        row[: c["push_fx_N"]] = (state.time_s, PHASES[s.phase], 0 if s.stance == "both" else
                                 1 + FEET.index(s.stance), *w.velocity, q[0], q[1], q[2], yaw, *com, *s.dcm,
                                 *s.dcm_ref, *s.zmp_ref, *s.cmp_clamped, s.zmp_ref_margin_m, s.cmp_margin_m)
        if self.pushes is not None:
            row[c["push_fx_N"]:c["push_fx_N"] + 2] = self.pushes.force_W[:2]
        row[c["controller_us"]] = sol.controller_time_s * 1e6
        row[c["qp_us"]] = sol.qp_time_s * 1e6
        for f in FEET:
            cs = w.wbc.contacts[f]
            fz_qp = float(sol.forces_W[f][:, 2].sum())
            i = c[f"{f}_weight"]
            if mon is None:
                row[i:i + 6] = (cs.weight, fz_qp, _NAN, _NAN, _NAN, _NAN)
                continue
            fz, (x, y) = mon.contacts[f].normal_n, mon.site_positions_W[f][:2].tolist()
            held = cs.active and cs.weight == 1.0
            slip = self._slip(f, held, fz >= SUPPORT_FRACTION * self.mg, x, y)
            row[i:i + 6] = (cs.weight, fz_qp, fz, x, y, slip)
        self._adaptation(s.adaptation)
        self._footprints(state.time_s)
        self.csv.write(row)
        self.k = k + 1
        fallen = mon is not None and mon.fall_reason is not None
        if self.pushes is not None and mon is not None:
            self.pushes.on_cycle(state.time_s, mon.sim.time_s, fallen)
        self.ctx.progress.advance()
        if k % VALUES_EVERY == 0:
            self.values()
        return fallen

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
        r = self.record().columns
        t = r["time_s"]
        walking = r["phase"] > 0
        dcm_err = np.hypot(r["dcm_x_m"] - r["dcm_ref_x_m"], r["dcm_y_m"] - r["dcm_ref_y_m"])
        observed = mon is not None
        slips = np.array(self.stance_slips + [v for f, v in self._stance_slip.items() if self._home[f]])
        force_err = {}
        if observed:
            err = np.abs(sum(r[f"{f}_fz_qp_N"] - r[f"{f}_fz_mj_N"] for f in FEET))
            for name, code in (("single", 1), ("double", 2)):
                stats = _stat(err[r["phase"] == code])
                rel = {f"{k}_rel_mg": None if v is None else v / self.mg for k, v in stats.items()}
                force_err[name] = {**{f"{k}_N": v for k, v in stats.items()}, **rel}
        gait = w.gait
        ctx.values.update({
            "fell": None if mon is None else mon.fall_reason is not None,
            "fall_reason": None if mon is None else mon.fall_reason,
            "fall_time_s": None if mon is None else mon.fall_time_s,
            "controller_fallback_at_s": w.wbc.infeasible_at_s,
            "qp_relaxed_cycles": w.wbc.relaxed_cycles,
            "controller_fallback_reason": w.wbc.infeasible_message,
            "steps": w.steps,
            "touchdowns": dict(gait.touchdowns) if gait is not None else {},
            "max_foot_slip_m": float(slips.max()) if observed and slips.size else None,
            "median_foot_slip_m": float(np.median(slips)) if observed and slips.size else None,
            "min_zmp_margin_m": float(np.min(r["zmp_ref_margin_m"][walking])) if walking.any() else None,
            "min_cmp_margin_m": float(np.min(r["cmp_margin_m"])),
            "cmp_clamped_fraction": float(np.mean(r["cmp_margin_m"] < w.config.cmp_margin_m - 1e-9)),
            "dcm_rms_m": float(np.sqrt(np.mean(dcm_err**2))),
            "dcm_max_error_m": float(dcm_err.max()),
            "contact_force_error": force_err if observed else None,
            "step_adaptations": dict(self.adaptations),
            "step_adaptation_qp_median_us": float(np.median(self._adapt_us)) if self._adapt_us else None,
            "controller_time_median_us": float(np.median(r["controller_us"])),
            "qp_solve_time_median_us": float(np.median(r["qp_us"][r["qp_us"] > 0])) if (r["qp_us"] > 0).any()
            else None,
            "walk_time_s": float(t[-1] - t[0]),
        })
        return ctx.values
