"""What ``mbctl view ROBOT --web`` and ``mbctl replay RUN_DIR --web`` serve: a robot or a run.

A run folder holds ``trajectory.npz`` + ``model.xml`` (every simulating job), ``report.json`` and
the job's CSV. The replay plays the trajectory, draws the reference path a job recorded in its
report (``reference.path_m``: the demo's square) and, when the CSV has per-foot contact columns
(``<site>_fz_mj_N`` with ``<site>_cop_x_mj_m``, ``<site>_cop_y_mj_m``, and the QP's ``_qp``
twins: g1-wbc), the normal force of each foot as an arrow at its centre of pressure. An arrow is
the force the floor exerts on the robot, pointing up for a standing robot, as the MP4's
contact-force arrows do (:mod:`mbctl.sim.video`: MuJoCo's own, one per contact point, from the
contact up). In the browser the arrow ends at the centre of pressure, its head touching the sole
from below the floor (seen through the grid): one arrow per foot starting there would run up
inside a straight leg, hidden. MuJoCo's thick and red, the QP's thin and blue inside it, so where
the two disagree one shows beyond the other.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_kinematics import PlantKinematics
from mbctl.sim.recorder import read_csv
from mbctl.sim.trajectory import base_body, load_trajectory
from mbctl.sim.web import Timeline, WebView, WebViewError

#: Arrow length per newton of contact force [m/N]: 2 mm per N (a standing G1 foot: ~0.34 m).
FORCE_SCALE_M_PER_N = 2e-3
#: Arrow colours: MuJoCo's measured forces and the controller's (QP) predicted ones.
MEASURED_RGB, PREDICTED_RGB = (220, 60, 30), (40, 90, 220)


def robot_view(robot: Robot, keyframe: str | None = None, port: int = 0) -> WebView:
    """``robot`` at ``keyframe`` (default qpos0), served on loopback."""
    m = robot.mj_model
    qpos = m.qpos0 if keyframe is None else m.key_qpos[robot.keyframe_id(keyframe)]
    view = WebView(m, port, base_body(robot), title=f"mbctl: {robot.name}")
    view.show(qpos)
    view.note(f"**{robot.name}**: nq {robot.nq}, nv {robot.nv}, nu {robot.mj_model.nu}"
              + (f"; keyframe `{keyframe}`" if keyframe else ""))
    return view


def _csv(run_dir: Path, report: dict) -> Path | None:
    name = report.get("outputs", {}).get("csv")
    candidates = [run_dir / Path(name).name] if name else []
    candidates += sorted(run_dir.glob("*.csv"))
    return next((p for p in candidates if p.is_file()), None)


def floor_z(model: mujoco.MjModel) -> float | None:
    """Height [m] of the model's floor (a world plane facing up), or None without one."""
    for g in range(model.ngeom):
        if (model.geom_bodyid[g] == 0 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE
                and abs(model.geom_quat[g][0]) > 0.9999):
            return float(model.geom_pos[g][2])
    return None


def _site_id(model: mujoco.MjModel, name: str) -> int | None:
    """The id of site ``name``, None when the model has no such site."""
    try:
        return int(model.site(name).id)
    except KeyError:
        return None


def contact_arrows(table: dict[str, np.ndarray], model: mujoco.MjModel, frame_rows: np.ndarray,
                   qpos: np.ndarray, source: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Per-frame normal-force arrows of the CSV's feet: (start, vector) (n, feet, 3) [m] in W.

    A foot is a site whose ``<site>_fz_<source>_N`` and CoP columns the CSV has (source ``mj``
    or ``qp``). The arrow is the force the floor exerts on the foot: it points up,
    ``FORCE_SCALE_M_PER_N``, and ends at the CoP on the floor (at the site's height without a
    floor), so it starts below the floor. Frames before
    the CSV's first row (``frame_rows`` -1) have none. None when the CSV has no such columns.
    """
    feet: list[str] = []
    sites: list[int] = []
    for f in (c[: -len(f"_fz_{source}_N")] for c in table if c.endswith(f"_fz_{source}_N")):
        site = _site_id(model, f)
        if site is not None and f"{f}_cop_x_{source}_m" in table and f"{f}_cop_y_{source}_m" in table:
            feet.append(f)
            sites.append(site)
    if not feet:
        return None
    kinematics = PlantKinematics(model)
    floor = floor_z(model)
    start = np.zeros((len(frame_rows), len(feet), 3))
    vec = np.zeros_like(start)
    for i, (row, q) in enumerate(zip(frame_rows, qpos, strict=True)):
        if row < 0:
            continue  # before the first control cycle: no force known
        data = kinematics.at_qpos(q)
        for k, (f, s) in enumerate(zip(feet, sites, strict=True)):
            start[i, k] = (table[f"{f}_cop_x_{source}_m"][row], table[f"{f}_cop_y_{source}_m"][row],
                           data.site_xpos[s][2] if floor is None else floor)
            vec[i, k, 2] = FORCE_SCALE_M_PER_N * table[f"{f}_fz_{source}_N"][row]
    return start - vec, vec  # the head at the CoP


def run_view(run_dir: Path, port: int = 0, fps: float = 30.0) -> WebView:
    """A recorded run served on loopback: play, pause and scrub; the path and forces it recorded.

    Frames are the trajectory resampled at ``fps`` per simulated second (the last sample at or
    before each frame time), so a long run stays light in the browser.

    Raises:
        FileNotFoundError: No trajectory in the folder.
        ValueError: The saved model does not load, or the report cannot be read.
    """
    run_dir = Path(run_dir)
    model, t, qpos, track = load_trajectory(run_dir)
    report_path = run_dir / "report.json"
    try:
        report = json.loads(report_path.read_text()) if report_path.is_file() else {}
    except (OSError, ValueError) as exc:  # (UnicodeDecodeError is a ValueError)
        raise ValueError(f"{report_path} cannot be read ({exc})") from None
    n = int(np.floor((t[-1] - t[0]) * fps + 1e-9)) + 1
    idx = np.searchsorted(t, t[0] + np.arange(n) / fps + 1e-9, side="right") - 1
    frames_t, frames_q = t[np.maximum(idx, 0)], qpos[np.maximum(idx, 0)]
    job = report.get("job", run_dir.name)
    view = WebView(model, port, track, title=f"mbctl replay: {job}")
    lines = [f"**{job}** ({report.get('status', 'no report')}), {t[-1] - t[0]:.2f} s simulated"]

    path = report.get("reference", {}).get("path_m")
    if path:
        view.add_path(np.asarray(path, dtype=float))
        lines.append("green: the reference path")
    draws = []
    csv_path = _csv(run_dir, report)
    if csv_path is not None:
        table = read_csv(csv_path)
        if "time_s" in table and len(table["time_s"]):
            rows = np.searchsorted(table["time_s"], frames_t + 1e-9, side="right") - 1
            shown = []
            for source, rgb, radius, what in (("mj", MEASURED_RGB, 0.012, "red (thick) MuJoCo's"),
                                              ("qp", PREDICTED_RGB, 0.005, "blue (thin) the QP's")):
                arrows = contact_arrows(table, model, rows, frames_q, source)
                if arrows is not None:
                    draws.append(view.add_arrows(f"/overlay/force_{source}", *arrows, rgb, radius))
                    shown.append(what)
            if shown:
                lines.append(f"arrows: {', '.join(shown)} normal force the floor exerts on each foot, "
                             f"pointing up to its centre of pressure (from below the floor), "
                             f"{FORCE_SCALE_M_PER_N * 1e3:g} mm per N")

    def on_frame(i: int) -> None:
        view.show(frames_q[i])
        for draw in draws:
            draw(i)

    view.note("  \n".join(lines))
    view.timeline(Timeline(frames_t, on_frame), fps)
    return view


def serve_until_interrupted(make_view: Callable[[], WebView]) -> None:
    """Build the web view, print its URL, serve until Ctrl-C (returns normally), then stop the server.

    Raises:
        WebViewError: ``make_view`` raised FileNotFoundError or ValueError (a run it cannot serve).
    """
    try:
        view = make_view()
    except (FileNotFoundError, ValueError) as exc:
        raise WebViewError(f"cannot serve this run: {exc}") from exc
    try:
        print(f"serving {view.url} (loopback only; from another machine: ssh -L "
              f"{view.port}:127.0.0.1:{view.port} HOST); Ctrl-C stops it", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("viewer stopped", flush=True)
    finally:
        view.close()
