"""A DDS run checked against what really happened: the bridge's truth log, aligned by LowState tick.

``mbctl serve g1`` writes ``truth.csv`` (one row per physics step, :data:`TRUTH_COLUMNS`, with the
tick of the LowState made at that step). A client records the tick of the state it used each
cycle, so its estimate at cycle k compares with the plant at the moment that state was measured,
whatever the link's delay.

Ticks restart with every bridge, so a tick alone does not say which run a log is of: each row
also has ``unix_s``, the wall-clock time it was made, and a log whose rows at the run's ticks were
not made while the run's control loop ran (within :data:`CLOCK_TOLERANCE_S`) is another run's,
refused (:class:`TruthLogError`, exit 2), as is a log without the rows.
"""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.loop import RunLog
from mbctl.jobs.runner import InputFoundBad
from mbctl.sim.dds_bridge import TRUTH_COLUMNS

#: A foot supports the robot (its slip counts) while the plant measures at least this fraction
#: of the robot's weight on it.
SUPPORT_FRACTION = 0.1
#: How far [s] the times a truth log's rows were made may lie outside the run's control loop: the
#: bridge's and the client's clocks (one machine: the same; two: NTP keeps them within
#: milliseconds) and the client's time between its loop's end and the check (milliseconds). Two
#: runs are further apart: a bridge starts in seconds.
CLOCK_TOLERANCE_S = 1.0


class TruthLogError(InputFoundBad):
    """A truth log that is missing, malformed, or from another run (bad input: exit 2)."""


def check_truth_header(path: str | Path) -> None:
    """Refuse, before a run, a file that is not a truth log of this mbctl (its columns).

    Raises:
        TruthLogError: A missing or unreadable file, or columns other than :data:`TRUTH_COLUMNS`.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as f:
            header = tuple(f.readline().strip().split(","))
    except (OSError, ValueError) as exc:
        raise TruthLogError(f"cannot read the truth log {path}: {exc}; give the truth.csv that "
                            "`mbctl serve g1 --output DIR` writes") from None
    if header != TRUTH_COLUMNS:
        raise TruthLogError(f"{path} is not a truth log of this mbctl (columns {', '.join(header[:5])}...; "
                            f"expected {', '.join(TRUTH_COLUMNS[:5])}...): give the truth.csv that "
                            "`mbctl serve g1 --output DIR` writes")


def read_truth(path: str | Path) -> np.ndarray:
    """The truth log as a structured array (one field per column).

    A bridge still running may be writing its last row as the client reads (its rows go out one
    write at a time): a last line without its newline is that row, left out; any other bad line
    is an error.

    Raises:
        TruthLogError: A missing or unreadable file, or columns other than :data:`TRUTH_COLUMNS`.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
            f.seek(0)
            whole_lines = (line for line in f if line.endswith("\n"))
            data = np.genfromtxt(whole_lines, delimiter=",", names=True, ndmin=1)
    except (OSError, ValueError) as exc:
        raise TruthLogError(f"cannot read the truth log {path}: {exc}; give the truth.csv that "
                            "`mbctl serve g1 --output DIR` wrote") from None
    if tuple(header) != TRUTH_COLUMNS or data.size == 0 or data.dtype.names is None:
        raise TruthLogError(f"{path} is not a bridge truth log (columns {header[:4]}..., {data.size} rows); "
                            "give the truth.csv that `mbctl serve g1 --output DIR` wrote")
    return data


def truth_at_ticks(truth: np.ndarray, ticks: np.ndarray) -> np.ndarray:
    """The truth rows (N,) at which the LowStates with ``ticks`` (N,) were made.

    Raises:
        TruthLogError: A tick the log does not have (a log from another run, or cut short).
    """
    rows = np.searchsorted(truth["tick"], ticks)
    rows = np.clip(rows, 0, truth.size - 1)
    missing = truth["tick"][rows] != ticks
    if missing.any():
        raise TruthLogError(f"the truth log has no row for LowState ticks {ticks[missing][:3].tolist()} "
                            f"(it covers {int(truth['tick'][0])}..{int(truth['tick'][-1])}): give the "
                            "truth.csv of the bridge this run talked to, written while it ran")
    return truth[rows]


def _utc(unix_s: float) -> str:
    return datetime.fromtimestamp(unix_s, timezone.utc).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def check_same_run(path: str | Path, at: np.ndarray, loop_unix_s: tuple[float, float]) -> None:
    """Refuse a truth log whose rows at the run's ticks were not made while the run's loop ran.

    Args:
        path: The truth log (for the message).
        at: Its rows at the run's ticks (N,) (of a repeated tick, the newest).
        loop_unix_s: When the run's control loop started and ended [s since the Unix epoch].

    Raises:
        TruthLogError: Rows made outside the loop's time, beyond :data:`CLOCK_TOLERANCE_S`.
    """
    start, end = loop_unix_s
    made = at["unix_s"]
    first, last = float(made.min()), float(made.max())
    if first >= start - CLOCK_TOLERANCE_S and last <= end + CLOCK_TOLERANCE_S:
        return
    raise TruthLogError(
        f"{path} is another run's truth log: its rows for this run's LowState ticks {int(at['tick'][0])}.."
        f"{int(at['tick'][-1])} were made {_utc(first)} to {_utc(last)} UTC, but this run's control loop "
        f"ran {_utc(start)} to {_utc(end)} UTC (ticks restart with every bridge); give the truth.csv of "
        f"the bridge this run talked to (its clock within {CLOCK_TOLERANCE_S:g} s of this machine's)")


def to_estimator_frame(at: np.ndarray, q_est: np.ndarray) -> np.ndarray:
    """The (x, y) shift [m] (2,) taking truth rows ``at`` into the estimator's world frame.

    A leg-kinematics estimator cannot observe its horizontal position: its W starts at (x, y) = the
    start it was given, so compare displacements in x, y (and absolute z, which the feet observe).

    Args:
        at: Truth rows at each cycle's state (N,).
        q_est: The run's estimated configurations (N, nq), Pinocchio convention.
    """
    return np.asarray(q_est[0, :2] - np.array([at["base_x_m"][0], at["base_y_m"][0]]))


def truth_com(path: str | Path, ticks: np.ndarray, q_est: np.ndarray) -> np.ndarray:
    """The robot's true CoM p_WC (N, 3) [m] in the estimator's W when each LowState with ``ticks`` was made.

    For a job comparing its CoM reference with the plant (g1-wbc's CoM RMS over DDS); ``q_est``
    (k, nq) are the run's estimated configurations, its first row the first cycle's (the loop's
    log rows: only that one is used, see :func:`to_estimator_frame`).

    Raises:
        TruthLogError: A missing or foreign log, or ticks it does not have.
    """
    at = truth_at_ticks(read_truth(path), np.asarray(ticks))
    com = np.column_stack([at["com_x_m"], at["com_y_m"], at["com_z_m"]])
    com[:, :2] += to_estimator_frame(at, q_est)
    return com


def stance_slips(window: np.ndarray) -> np.ndarray:
    """Each stance's largest horizontal drift [m] of the foot from where it started to support.

    A foot supports while the plant measures at least :data:`SUPPORT_FRACTION` of the window's
    first total normal force on it; a stance is a run of such rows, its drift counted from the row
    before it (the foot's place before it was loaded; the first row for a stance from the start).
    Stances of both feet, the left's first (a walk's; a standing run has one per foot).
    """
    weight = window["left_foot_fz_N"][0] + window["right_foot_fz_N"][0]
    out: list[float] = []
    for side in ("left", "right"):
        xy = np.column_stack([window[f"{side}_foot_x_m"], window[f"{side}_foot_y_m"]])
        loaded = window[f"{side}_foot_fz_N"] >= SUPPORT_FRACTION * weight
        edges = np.flatnonzero(np.diff(np.concatenate(([False], loaded, [False])).astype(np.int8)))
        for start, stop in zip(edges[::2], edges[1::2], strict=True):  # [start, stop) loaded
            home = xy[max(start - 1, 0)]
            out.append(float(np.hypot(*(xy[start:stop] - home).T).max()))
    return np.array(out)


def truth_checks(path: str | Path, ticks: np.ndarray, log: RunLog,
                 fall_height_m: float | None, loop_unix_s: tuple[float, float]) -> dict[str, Any]:
    """The plant checks of a DDS run and the estimator's errors, from the bridge's truth log.

    Args:
        path: The truth log.
        ticks: LowState tick of each cycle's state (N,) (the log's ``tick``: every cycle).
        log: The run's log (its q holds the estimated base pose, at the rows it kept).
        fall_height_m: Pelvis height [m] below which the robot has fallen (the robot's fall rule,
            e.g. ``mbctl.robots.g1.G1_FALL.base_min_z_m``; None: no verdict).
        loop_unix_s: When the run's control loop started and ended [s since the Unix epoch]: the
            log's rows at ``ticks`` must have been made then (:func:`check_same_run`).

    Returns:
        Report values: ``truth_pelvis_max_deviation_m``, ``truth_pelvis_z_min_m``, ``truth_fell``,
        ``truth_max_foot_slip_m`` (0 with no stance), ``truth_median_foot_slip_m`` (over the feet's
        stances, :func:`stance_slips`; None with none),
        ``estimator_position_error_max_m``, ``estimator_position_error_final_m``,
        ``estimator_orientation_error_max_deg`` (the two largest: None when the log kept every
        ``stride``-th cycle; ``estimator_errors_over`` says which), ``truth_rows``,
        ``truth_commands_applied`` (commands the bridge applied while the run's states were made).
    """
    truth = read_truth(path)
    at = truth_at_ticks(truth, ticks)
    # a state held before the first command repeats its tick: its newest row is when the run read it
    check_same_run(path, truth[np.searchsorted(truth["tick"], ticks, side="right") - 1], loop_unix_s)
    first = int(np.searchsorted(truth["tick"], ticks.min()))
    last = int(np.searchsorted(truth["tick"], ticks.max()))
    window = truth[first:last + 1]
    dz = window["base_z_m"] - window["base_z_m"][0]
    rows = at[log.cycle]  # the truth at the log's rows (every cycle, or every stride-th and the last)
    p_true = np.column_stack([rows["base_x_m"], rows["base_y_m"], rows["base_z_m"]])
    p_est = log.q[:, 0:3].copy()
    p_est[:, :2] -= to_estimator_frame(rows, log.q)
    err = np.linalg.norm(p_est - p_true, axis=1)
    angles = []
    for k in range(len(rows)):
        r = rows[k]
        R_true = pin.Quaternion(r["base_qw"], r["base_qx"], r["base_qy"], r["base_qz"])
        R_est = pin.Quaternion(log.q[k, 6], log.q[k, 3], log.q[k, 4], log.q[k, 5])
        angles.append(R_true.angularDistance(R_est))
    every = log.stride == 1  # the largest errors need every cycle's estimate: else unchecked (null)
    deviation = float(np.abs(dz).max())
    slips = stance_slips(window)
    return {
        "truth_rows": int(window.size),
        "truth_commands_applied": int(window["commands_applied"][-1] - window["commands_applied"][0]),
        "truth_pelvis_max_deviation_m": deviation,
        "truth_pelvis_z_min_m": float(window["base_z_m"].min()),
        "truth_fell": bool(fall_height_m is not None and window["base_z_m"].min() < fall_height_m),
        "truth_max_foot_slip_m": float(slips.max()) if slips.size else 0.0,
        "truth_median_foot_slip_m": float(np.median(slips)) if slips.size else None,
        "estimator_position_error_max_m": float(err.max()) if every else None,
        "estimator_position_error_final_m": float(err[-1]),
        "estimator_orientation_error_max_deg": float(np.degrees(max(angles))) if every else None,
        "estimator_errors_over": ("every cycle" if every else
                                  f"not checked: the loop's log kept every {log.stride}th of {log.cycles} "
                                  "cycles (control.loop.MAX_LOG_ROWS); run shorter pieces to check them"),
    }
