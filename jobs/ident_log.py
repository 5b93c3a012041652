"""The identification log: what ``mbctl excite`` records and ``mbctl identify`` reads, in one place.

A run folder holds ``excite.csv`` (one row per control cycle, streamed) and ``report.json``,
whose ``identification_log`` section says how to read it. Columns, Pinocchio's convention:

* ``time_s``; the full q (:func:`~mbctl.jobs.recording.q_columns`) and v (``v_columns``),
* ``tau_<joint>_N_m``: the torque on each actuated joint over the cycle that starts at the
  row's state. In-process, what the actuators applied (MuJoCo's ``qfrc_actuator`` after the step:
  clamped, geared); over DDS, what the cycle commanded (the LowCmd's ``tau`` in torque mode,
  ``kp = kd = 0``), not the motors' ``tau_est`` (:data:`TORQUES`, and the identification guide),
* per contact body B (the feet of a robot that stands): ``contact_<B>`` (1 while touching) and,
  in-process, its contact wrench ``w_<B>_fx_N`` ... ``w_<B>_mz_N_m`` (force, and moment about B's
  origin, world axes: what a foot force sensor would give; ``identify`` uses it only when asked).
  Over DDS nothing measures the feet: the flag is the controller's (the foot's contact constraint
  in force) and there are no wrench columns,
* ``other_contacts`` (in-process): contacts on the robot elsewhere (samples identification must
  not use); over DDS nothing counts them and the column is absent.

The section: the robot (name or file, scene, gravity, Menagerie folder), the dynamics
fingerprint of the nominal model, the joints of the torque columns, the contact bodies, the
timestep and control period, where the torques and contacts come from, and the excitation.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from mbctl.jobs.recording import q_columns, v_columns
from mbctl.robots.identification import BadLogError, RecordedLog
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.sim.monitor import PlantMonitor

SECTION = "identification_log"
CSV_NAME = "excite.csv"
WRENCH = ("fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m")
#: What the torque and contact columns hold, by plant (the section's ``torques`` and ``contacts``).
TORQUES = {"measured": "applied by the plant's actuators over the cycle (MuJoCo's qfrc_actuator)",
           "commanded": "commanded for the cycle (LowCmd tau, torque mode kp = kd = 0), not the motors' "
                        "tau_est: the torque held over the cycle, noise-free, as the samples' forward "
                        "differences assume; the gap to the link's torque is the joint friction and "
                        "armature that --friction and --armature identify"}
CONTACTS = {"measured": "touching, with the wrenches, measured by the plant",
            "commanded": "the controller's contact constraints (no force sensor: no wrenches)"}


def tau_columns(joints: tuple[str, ...]) -> list[str]:
    """``tau_<joint>_N_m`` per joint."""
    return [f"tau_{j}_N_m" for j in joints]


def contact_columns(bodies: tuple[str, ...]) -> list[str]:
    """``contact_<B>`` and the six wrench columns per contact body."""
    out: list[str] = []
    for b in bodies:
        out += [f"contact_{b}", *(f"w_{b}_{w}" for w in WRENCH)]
    return out


def header(robot: Robot, joints: tuple[str, ...], bodies: tuple[str, ...],
           measured: bool = True) -> list[str]:
    """The CSV's columns (see the module docstring); ``measured=False``: a DDS log (flags only, no counts)."""
    if not measured:
        return ["time_s", *q_columns(robot), *v_columns(robot), *tau_columns(joints),
                *(f"contact_{b}" for b in bodies)]
    return ["time_s", *q_columns(robot), *v_columns(robot), *tau_columns(joints), *contact_columns(bodies),
            "other_contacts"]


def command_row(state: RobotState, tau: np.ndarray, contacts: np.ndarray) -> list[float]:
    """One row of a DDS log (:func:`header` with ``measured=False``).

    Args:
        state: The state the cycle's command was computed from (base estimated).
        tau: The torques the cycle commanded (k,) [N m], in the header's joint order.
        contacts: Whether the controller held each contact body on the ground (c,).
    """
    return [state.time_s, *state.q, *state.v, *tau, *(float(c) for c in contacts)]


def log_row(state: RobotState, monitor: PlantMonitor) -> list[float]:
    """One row of the log (the columns of :func:`header`): the cycle's state and what the plant measured.

    Args:
        state: The state the cycle's command was computed from.
        monitor: The plant's monitor right after the cycle, built with the header's ``joints``,
            its contact bodies as ``wrench_bodies`` and ``count_elsewhere=True``.
    """
    row = [state.time_s, *state.q, *state.v, *monitor.joint_torques]
    for on, wrench in zip(monitor.touching, monitor.wrenches_W, strict=True):
        row += [float(on), *wrench]
    row.append(monitor.contacts_elsewhere)
    return row


def read_run(run_dir: Path) -> tuple[RecordedLog, dict[str, Any]]:
    """The log of an ``mbctl excite`` run folder and its ``identification_log`` section.

    Raises:
        BadLogError: No such folder, no report or CSV, a report without the section (not an
            excite run), missing columns, or rows that do not parse.
    """
    run_dir = Path(run_dir)
    report_path, csv_path = run_dir / "report.json", run_dir / CSV_NAME
    if not run_dir.is_dir():
        raise BadLogError(f"{run_dir} is not a folder; give the run folder of an `mbctl excite` run")
    if not report_path.is_file():
        raise BadLogError(f"{run_dir} has no report.json: not a run folder (record one with mbctl excite)")
    try:
        report = json.loads(report_path.read_text())
    except (OSError, ValueError) as exc:
        raise BadLogError(f"{report_path} cannot be read: {exc}") from None
    section = report.get(SECTION) if isinstance(report, dict) else None
    if not isinstance(section, dict):
        job = report.get("job", "?") if isinstance(report, dict) else "?"
        if job == "excite":
            raise BadLogError(incomplete_message(run_dir, report))
        raise BadLogError(f"{run_dir} was recorded by `mbctl {job}`, not `mbctl excite`: "
                          f"its report has no {SECTION!r} section; record an excitation with mbctl excite")
    if not csv_path.is_file():
        raise BadLogError(f"{run_dir} has no {CSV_NAME}; the run wrote no rows")
    with csv_path.open() as f:
        names = f.readline().strip().split(",")
    joints = tuple(section["joints"])
    bodies = tuple(section.get("contact_bodies", ()))
    needed = ["time_s", *section["q_columns"], *section["v_columns"], *tau_columns(joints)]
    if bodies:
        needed += [f"contact_{b}" for b in bodies]
    missing = [c for c in needed if c not in names]
    if missing:
        raise BadLogError(f"{csv_path} lacks the columns {missing[:6]}" + (" ..." if len(missing) > 6 else "")
                          + f" ({len(missing)} missing); identification needs q, v and the applied torques")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data": reported below
            data = np.loadtxt(csv_path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise BadLogError(f"{csv_path} has a row that is not numbers: {exc}") from None
    if data.size == 0:
        raise BadLogError(f"{csv_path} has no rows: the log is too short (record a longer excitation)")
    if data.shape[1] != len(names):
        raise BadLogError(f"{csv_path} has {data.shape[1]} values per row and {len(names)} column names")
    col = {n: i for i, n in enumerate(names)}
    check_time_increases(csv_path, data[:, col["time_s"]])

    def cols(keys: list[str]) -> np.ndarray:
        return data[:, [col[k] for k in keys]]

    contacts = wrenches = None
    if bodies:
        contacts = cols([f"contact_{b}" for b in bodies]) > 0.5
        wrench_cols = [f"w_{b}_{w}" for b in bodies for w in WRENCH]
        if all(c in col for c in wrench_cols):
            wrenches = cols(wrench_cols).reshape(len(data), len(bodies), 6)
    others = data[:, col["other_contacts"]].astype(int) if "other_contacts" in col else None
    log = RecordedLog(data[:, col["time_s"]], cols(section["q_columns"]), cols(section["v_columns"]),
                      cols(tau_columns(joints)), joints, bodies, contacts, wrenches, others)
    return log, section


def incomplete_message(run_dir: Path, report: dict[str, Any]) -> str:
    """Why an ``mbctl excite`` run folder without the log's section cannot be identified, and what to do.

    The section comes with the run's final report: a run killed before it (SIGKILL, power loss)
    keeps the report written at the start, which still says ``running``; a run that failed before
    its log was set up says why in its status and message.
    """
    status = report.get("status", "?")
    if status == "running":
        why = (f"its report.json still says status 'running' (pid {report.get('pid', '?')}): the run is "
               "still going, or was killed (SIGKILL, power loss) before it wrote its report")
    else:
        why = (f"it ended with status {status!r} ({report.get('message') or 'no message'}) before its log "
               "began")
    return (f"{run_dir} holds an incomplete `mbctl excite` run: {why}, so its report has no {SECTION!r} "
            f"section and {CSV_NAME} cannot be read; wait for a running excitation to finish, or record it "
            "again with mbctl excite (a run stopped with Ctrl-C or SIGTERM keeps its report and can be "
            "identified)")


def check_time_increases(csv_path: Path, t_s: np.ndarray) -> None:
    """Every row's ``time_s`` after the previous one's (NaN is left to the finiteness check).

    Raises:
        BadLogError: The first data row (0-based, after the header) whose time does not increase,
            with both times: reversed, shuffled or repeated rows.
    """
    bad = np.flatnonzero(np.diff(t_s) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        now, before = float(t_s[k]), float(t_s[k - 1])
        raise BadLogError(f"{csv_path} has non-increasing time: data row {k} has time_s {now!r} s after "
                          f"{before!r} s at row {k - 1} ({bad.size} such rows); a log's rows are in the "
                          "order they were recorded, time strictly increasing (reversed, shuffled or "
                          "repeated rows?)")
