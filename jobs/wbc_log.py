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
from typing import Any, NamedTuple

import numpy as np

from mbctl.control.loop import MAX_LOG_ROWS, batch_rows, kept_cycles, log_rows, log_stride
from mbctl.control.wbc import Standing
from mbctl.jobs.log_sums import CoMErrorSums, nan_max, nan_min, quantile
from mbctl.jobs.runner import RunContext
from mbctl.jobs.state_fall import StateFallWatch
from mbctl.jobs.wbc_stage import S_CTRL, S_FALLBACK, S_FEET, S_NOW, S_PHYSICS, S_QP, S_T_PLANT, WBCStage
from mbctl.robots.commands import Command
from mbctl.robots.g1 import FEET
from mbctl.robots.interface import RobotState
from mbctl.sim.contacts import sums_block
from mbctl.sim.monitor import PlantMonitor
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
#: Cycles :meth:`WBCLog.on_step` stages before recording them over a link with deadlines (a fraction
#: of a ms of recording at once, within the G1's 2 ms period beside its cycle).
BATCH = 64
#: The same in-process, where no deadline waits (about 2 ms of recording at once, every 2 s of the G1's
#: time): a batch's recording has a fixed part (numpy calls per field, ~0.3 ms) that larger batches
#: share out (on_step's mean 9.3 -> 8.0-8.3 us a cycle from 256; the staging arrays ~1.4 MB).
BATCH_IN_PROCESS = 1024
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
        batch: Cycles kept before they are recorded (:data:`BATCH`, :data:`BATCH_IN_PROCESS`).
    """

    def __init__(self, ctx: RunContext, wb: Standing, monitor: PlantMonitor | None,
                 pushes: PushSchedule | None, n: int, mg_n: float, q_names: list[str], batch: int = BATCH):
        self.ctx, self.wb, self.monitor, self.pushes, self.mg = ctx, wb, monitor, pushes, mg_n
        self.batch = batch
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
        # q go to the CSV only. A cycle not kept is written to the next kept row's place and
        # overwritten, as the control loop's log does: the run's last cycle is always kept.
        w, nf, nt = len(header), len(FEET), len(ctrl.joints.actuators)
        feet_at = header.index(f"{FEET[0]}_fz_qp_N")
        self._tau = slice(feet_at + _PER_FOOT * nf, feet_at + _PER_FOOT * nf + nt)
        self._q = slice(self._tau.stop, w)
        self._feet_at, self._width = feet_at, w
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
        self.state_fall = StateFallWatch()  # over DDS (no monitor): the fall rule on the estimated state
        self._last_cycle_end: float | None = None
        # each cycle's values, staged by on_step as the cycle ends (a few row stores while they are
        # in the CPU's caches) and recorded a batch at a time; sized at the first cycle (by its solution)
        self.staged = 0
        self._stage: WBCStage | None = None
        self._foot_states = [ctrl.contacts[f] for f in FEET]
        self._home: dict[str, tuple[float, float]] = {}  # where each foot started to support
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

    def on_step(self, k: int, state: RobotState, reference: object, command: Command) -> bool:
        """Stage cycle ``k`` (the loop's ``on_step``); True once the robot has fallen (ends the run).

        The cycle's values are copied into the staging arrays (:class:`WBCStage`) and recorded
        ``batch`` cycles at a time, and by every reader (:meth:`record`, :meth:`values`), with one
        numpy call per quantity. Keeping each cycle's objects instead and reading them back a batch
        at a time read them cold from memory, and kept the allocator from reusing their memory while
        it was warm: about 2.5 ms a 256-cycle batch on the G1, twice what the stores cost.
        """
        now = time.perf_counter()
        i, st, mon, sol = self.staged, self._stage, self.monitor, self.wb.controller.last
        assert sol is not None  # the cycle's compute, which ran, set it
        if st is None:
            st = self._stage = WBCStage(self.batch, sol, len(state.q), len(command.values), mon)
        left, right = self._foot_states
        if mon is not None:
            p = mon.sample
            st.scalars[i] = (state.time_s, p.time_s, p.physics_time_s, sol.controller_time_s, sol.qp_time_s,
                             sol.fallback, left.active, left.weight, right.active, right.weight, now)
            st.com[i] = p.com_W
            st.sites[i] = p.site_array_W
            st.net[i] = p.contact_net
        else:  # over DDS: the controller's CoM (from the estimated state), the state's time
            st.scalars[i] = (state.time_s, state.time_s, 0.0, sol.controller_time_s, sol.qp_time_s,
                             sol.fallback, left.active, left.weight, right.active, right.weight, now)
            st.com[i] = self.wb.controller.state.com()
        st.q[i] = state.q
        st.tau[i] = command.values
        st.ref[i] = self.wb.com.target
        st.forces[i] = sol.forces
        st.X[i] = sol.foot_X_W
        if self.pushes is not None:
            st.push[i] = self.pushes.force_W[:2]
        self.staged = i + 1
        if i + 1 >= self.batch:
            self._drain()
        return mon.fall_reason is not None if mon is not None else self.state_fall.check(state)

    def _drain(self) -> None:
        """Record the cycles staged so far, in order (the progress bar advances by them).

        Interrupted (Ctrl-C) before the batch's CSV rows are written, the batch stays staged and the
        next reader (the runner's :meth:`values` at the end) records it: every completed cycle's row
        is kept. Nothing the batch changes is changed before its rows are written.
        """
        if self.staged:
            n = self.staged
            self._record(self._stage, n)  # type: ignore[arg-type]  # staged cycles have a stage
            self.ctx.progress.advance(n)

    def _record(self, st: WBCStage, b: int) -> None:
        """Record the ``b`` cycles :meth:`on_step` staged, as arrays over the batch (see :meth:`_drain`)."""
        mon, x, k0 = self.monitor, self._extra, self.k
        S = st.scalars[:b]
        t, q, ref, com, push = S[:, 0].copy(), st.q[:b], st.ref[:b], st.com[:b], st.push[:b]
        if not k0:
            self._t0 = float(t[0])
        block = np.empty((b, self._width))  # the CSV's rows
        block[:, 0], block[:, 1:4], block[:, 4:7], block[:, 7], block[:, 8:10] = t, ref, com, q[:, 2], push
        cols = block[:, self._feet_at:self._tau.start].reshape(b, len(FEET), _PER_FOOT)  # a view of block
        qp = cols[:, :, :4]
        qp[:] = st.qp_feet(b)
        state_feet = S[:, S_FEET].reshape(b, len(FEET), 2)  # active, weight
        supporting = (state_feet[:, :, 0] > 0.5) & (state_feet[:, :, 1] == 1.0)
        stance = supporting.all(axis=1) & (S[:, S_FALLBACK] < 0.5)
        if mon is None:  # over DDS: the plant's forces and feet are not observed
            cols[:, :, 4:] = _NO_PLANT
            slip = np.zeros((b, len(FEET)))
        else:  # the monitor's groups and sites in FEET order
            sums = sums_block(st.net[:b])[:, self._groups]  # (b, n_feet, 6)
            fz = sums[:, :, 2]
            with np.errstate(divide="ignore", invalid="ignore"):  # the CoP, as contacts'
                cols[:, :, 6:8] = np.where((fz > 1e-9)[:, :, None], sums[:, :, 3:5] / fz[:, :, None], np.nan)
            cols[:, :, 4] = fz
            cols[:, :, 5] = np.hypot(sums[:, :, 0], sums[:, :, 1])
            xy = st.sites[:b, self._sites, :2]
            slip = cols[:, :, 8]
            slip[:], homes = self._slips(supporting & (fz >= SUPPORT_FRACTION * self.mg), xy)
        block[:, self._tau] = st.tau[:b]
        block[:, self._q] = q
        self.csv.write_rows(block)
        self.staged = 0  # the batch is in the CSV: from here on it is never recorded again
        if mon is not None:
            self._home = homes
        # the kept rows: the CSV's columns, then the record's others
        at, rows = batch_rows(k0, b, self.stride)
        kept = self._rows[rows]
        kept[:, :self._tau.start] = block[at, :self._tau.start]
        t_plant = S[:, S_T_PLANT]
        ctrl_us = S[:, S_CTRL] * 1e6
        qp_us = S[:, S_QP] * 1e6
        slip_max = slip.max(axis=1)
        last = self._last_cycle_end
        nows = S[:, S_NOW]
        cycle_us = np.diff(nows, prepend=math.nan if last is None else last) * 1e6
        self._last_cycle_end = float(nows[-1])
        com_err = self.com_sums.add_block(t, ref, t_plant, com)
        for name, values in (("t_plant", t_plant), ("stance", stance), ("ctrl_us", ctrl_us), ("qp_us", qp_us),
                             ("slip", slip_max), ("cycle_us", cycle_us), ("com_err_t", com_err[:, 0]),
                             ("com_err_m", com_err[:, 1])):
            kept[:, x[name]] = values[at]
        # every cycle's extremes (NaN-propagating, as nan_max and nan_min)
        self._slip_max = nan_max(self._slip_max, float(slip_max.max()))
        self._z_min = nan_min(self._z_min, float(q[:, 2].min()))
        quantiles = self._quantiles[k0:k0 + b]
        if mon is None:
            self._com_ref[k0:k0 + b] = ref
            quantiles[:] = np.column_stack((ctrl_us, qp_us, cycle_us))
        else:
            physics_us = S[:, S_PHYSICS] * 1e6
            kept[:, x["physics_us"]] = physics_us[at]
            fz_qp, fz_mj = qp[:, :, 0], cols[:, :, 4]
            rel = np.abs(fz_qp.sum(axis=1) - fz_mj.sum(axis=1)) / self.mg
            settled = t >= self._t0 + SETTLE_S
            counted = stance & settled
            if counted.any():
                self._rel_max = nan_max(self._rel_max, float(rel[counted].max()))
            if not settled.all():
                self._settling_max = nan_max(self._settling_max, float(rel[~settled].max()))
            quantiles[:] = np.column_stack((counted, rel, *(np.abs(fz_qp - fz_mj) / self.mg).T, ctrl_us,
                                            qp_us, cycle_us, physics_us))
        self._rows[rows] = kept
        self.k = k0 + b
        self._row = -(-self.k // self.stride)

    def _slips(self, loaded: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, dict[str, tuple[float, float]]]:
        """Each foot's slip [m] over a batch: how far its site moved while it supports (0 otherwise).

        A foot's slip counts from where it was when it last did not support (or, supporting since
        the run began, where it first did).

        Args:
            loaded: (b, n_feet) the foot supports at full weight and MuJoCo measures >= 10 % of m g on it.
            xy: (b, n_feet, 2) its site's x, y [m] in W.

        Returns:
            The slips (b, n_feet) and each foot's place to count from after the batch (the log's
            ``_home`` is not changed here).
        """
        b = len(loaded)
        slip = np.zeros(loaded.shape)
        homes = dict(self._home)
        for j, f in enumerate(FEET):
            # each cycle's home: the site at the last cycle not supporting (-1: none in this batch)
            last = np.maximum.accumulate(np.where(loaded[:, j], -1, np.arange(b)))
            home = xy[np.maximum(last, 0), j]
            carried = homes.get(f, tuple(xy[0, j].tolist()))
            home[last < 0] = carried
            d = xy[:, j] - home
            slip[:, j] = np.where(loaded[:, j], np.hypot(d[:, 0], d[:, 1]), 0.0)
            homes[f] = tuple(home[-1].tolist()) if last[-1] < 0 else tuple(xy[last[-1], j].tolist())
        return slip, homes

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
                                "com_error_source": "truth log", **self.state_fall.truth_values(fell)})
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
            **self.state_fall.values(mon),
            "controller_fallback_at_s": ctrl.infeasible_at_s,
            "qp_relaxed_cycles": ctrl.relaxed_cycles,
            # over DDS the estimated CoM's (with_truth replaces it by the truth log's)
            "com_error_rms_m": com.rms(),
            "max_foot_slip_m": self._slip_max if mon is not None else None,  # over DDS: the truth log's
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
            # its mean: the recording's batches (``batch`` cycles at once) and the CSV's flushes included
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
