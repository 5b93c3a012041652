"""Plots of ``mbctl g1-walk``: the walk from above, and each foot's normal force with the gait phases."""

from __future__ import annotations

from typing import Any

import numpy as np

from mbctl.control.wbc import WalkingController
from mbctl.jobs.g1_walk_log import PHASES, WalkLog
from mbctl.jobs.log_sums import rows_note
from mbctl.jobs.plots import new_figure
from mbctl.jobs.runner import RunContext
from mbctl.planners import convex_hull
from mbctl.robots.g1 import FEET

#: Colours of the feet (left, right) and of double support.
FOOT_COLORS = ("C0", "C1")
DOUBLE_COLOR = "0.75"
#: Colour of the waypoints and pushes (apart from the paths' colours).
MARK_COLOR = "C4"
#: The box behind a mark's label (over the footprints and paths).
LABEL_BOX = {"boxstyle": "round,pad=0.2", "fc": "w", "ec": MARK_COLOR, "alpha": 0.85}


def walk_plots(ctx: RunContext, log: WalkLog, walker: WalkingController, params: Any,
               values: dict[str, Any]) -> None:
    """Save ``g1_walk.png`` (from above) and ``g1_walk_forces.png`` (normal forces, phases shaded).

    The curves are the log's kept rows (every ``stride``-th cycle of a long run, said in the titles).
    """
    r = log.record()
    if not log.k:
        return
    note = rows_note(log.stride, log.k)
    _top_view(ctx, log, walker, params, values, note)
    _forces(ctx, r.columns, r.foot, params, values, note)


def _top_view(ctx: RunContext, log: WalkLog, walker: WalkingController, params: Any,
              values: dict[str, Any], note: str) -> None:
    """Footprints (each sole where it stood or landed), CoM, DCM and ZMP reference paths, from above."""
    c = log.record().columns
    sole = convex_hull(walker.wbc.contacts[FEET[0]].contact.points_F[:, :2])
    fig, axes = new_figure(1, 1, (11.0, 7.0), layout="constrained")
    ax = axes[0][0]
    for _, foot, x, y, yaw in log.footprints:
        cs, sn = np.cos(yaw), np.sin(yaw)
        outline = sole @ np.array([[cs, sn], [-sn, cs]]) + [x, y]
        closed = np.vstack([outline, outline[:1]])
        color = FOOT_COLORS[FEET.index(foot)]
        ax.fill(closed[:, 0], closed[:, 1], color=color, alpha=0.25, lw=0)
        ax.plot(closed[:, 0], closed[:, 1], color=color, lw=0.8)
    for f, color in zip(FEET, FOOT_COLORS, strict=True):
        ax.plot([], [], color=color, lw=4, alpha=0.4, label=f"{f} footprints")
    walking = c["phase"] > 0
    ax.plot(c["zmp_ref_x_m"][walking], c["zmp_ref_y_m"][walking], color="C2", lw=0.9, label="ZMP reference")
    ax.plot(c["dcm_ref_x_m"], c["dcm_ref_y_m"], color="C3", lw=0.9, ls="--", label="DCM plan")
    ax.plot(c["dcm_x_m"], c["dcm_y_m"], color="C3", lw=1.2, label="DCM measured")
    ax.plot(c["com_x_m"], c["com_y_m"], color="k", lw=1.5, label="CoM (MuJoCo)" if log.monitor else "CoM")
    draw_waypoints(ax, values.get("waypoints") or [])
    draw_pushes(ax, c, values.get("pushes") or [])
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m, world)")
    ax.set_ylabel("y (m, world)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    verdict = "FELL" if values["fell"] else "walked"
    command = ", ".join(f"{v:g}" for v in params.command)
    moved = (f"{values['path_m']:.2f} m walked" if "path_m" in values else f"{values['distance_m']:.2f} m")
    gait = f", {params.gait} gait"
    fig.suptitle(f"G1 walking, {params.scenario} at ({command}){gait}: {verdict}, {values['steps']} steps, "
                 f"{moved}; DCM RMS {values['dcm_rms_m'] * 1e3:.1f} mm" + note)
    ctx.save_figure(fig, "g1_walk.png")


def draw_waypoints(ax: Any, waypoints: list[dict[str, Any]]) -> None:
    """A course's waypoints: numbered, an arrow along each one's yaw, a dot when reached, a cross when not."""
    for i, w in enumerate(waypoints, start=1):
        x, y, yaw = w["x_m"], w["y_m"], np.radians(w["yaw_deg"])
        ax.annotate("", (x + 0.15 * np.cos(yaw), y + 0.15 * np.sin(yaw)), (x, y),
                    arrowprops={"arrowstyle": "->", "color": MARK_COLOR, "lw": 1.5})
        ax.plot(x, y, ls="none", ms=9, zorder=5, **_waypoint_marker(w["reached_at_s"] is not None))
        ax.annotate(str(i), (x, y), textcoords="offset points", xytext=(8, 8), fontsize=9, color=MARK_COLOR,
                    weight="bold", zorder=6, bbox=LABEL_BOX)
    for reached, label in ((True, "waypoint reached"), (False, "waypoint not reached")):
        if any((w["reached_at_s"] is not None) == reached for w in waypoints):
            ax.plot([], [], ls="none", ms=8, label=label, **_waypoint_marker(reached))


def _waypoint_marker(reached: bool) -> dict[str, Any]:
    """A dot when reached, a hollow cross when not."""
    return {"marker": "o" if reached else "X", "mfc": MARK_COLOR if reached else "w", "mec": MARK_COLOR}


def draw_pushes(ax: Any, c: dict[str, np.ndarray], pushes: list[dict[str, Any]]) -> None:
    """Each push: an arrow in its direction onto the CoM's place at the push, its impulse (and "fell")."""
    span_m = max(float(np.ptp(c["com_x_m"])), float(np.ptp(c["com_y_m"]))) if len(c["com_x_m"]) else 0.0
    length_m = max(0.25, 0.07 * span_m)  # readable on a long walk's plot too
    for p in pushes:
        k = min(int(np.searchsorted(c["time_s"], p["time_s"])), len(c["time_s"]) - 1)
        x, y = c["com_x_m"][k], c["com_y_m"][k]
        u = np.array([np.cos(np.radians(p["direction_deg"])), np.sin(np.radians(p["direction_deg"]))])
        text = f"{p['impulse_n_s']:g} N s" + ("" if p["survived"] else ", fell")
        arrow = {"arrowstyle": "-|>", "color": MARK_COLOR, "lw": 2.0}
        ax.annotate(text, (x, y), (x - length_m * u[0], y - length_m * u[1]), color=MARK_COLOR, fontsize=9,
                    ha="center", va="center", arrowprops=arrow, zorder=6, bbox=LABEL_BOX)
    if pushes:
        ax.plot([], [], color=MARK_COLOR, lw=2.0, label="push on the pelvis (at the CoM's place)")


def _shade_phases(ax: Any, t: np.ndarray, phase: np.ndarray, stance: np.ndarray) -> None:
    """Shade single support by the stance foot's colour, double support grey."""
    key = np.where(phase == PHASES["double"], -1, np.where(phase == PHASES["single"], stance, 0))
    edges = np.flatnonzero(np.diff(key)) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, len(t)], strict=True):
        k = key[a]
        if k == 0:
            continue
        color = DOUBLE_COLOR if k == -1 else FOOT_COLORS[int(k) - 1]
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color=color, alpha=0.15 if k > 0 else 0.35, lw=0)


def _forces(ctx: RunContext, c: dict[str, np.ndarray], feet: dict[str, dict[str, np.ndarray]], params: Any,
            values: dict[str, Any], note: str) -> None:
    """Per foot: the normal force, QP dashed over MuJoCo solid, single support shaded by foot, double grey."""
    t = c["time_s"]
    fig, axes = new_figure(len(FEET), 1, (13.0, 3.2 * len(FEET) + 0.8), layout="constrained")
    for i, (f, color) in enumerate(zip(FEET, FOOT_COLORS, strict=True)):
        ax = axes[i][0]
        _shade_phases(ax, t, c["phase"], c["stance"])
        ax.plot(t, feet[f]["fz_mj_N"], color=color, lw=1.2, label="MuJoCo")
        ax.plot(t, feet[f]["fz_qp_N"], color="k", lw=0.9, ls="--", label="QP")
        ax.set_ylabel(f"{f}\nnormal force (N)")
        ax.set_xlabel("time (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    force = (values.get("contact_force_error") or {}).get("single") or {}
    median = force.get("median_N")
    fig.suptitle(f"{params.scenario}: normal force per foot, QP (dashed) and MuJoCo (solid); shaded: single "
                 f"support (the stance foot's colour), double support (grey); |QP - MuJoCo| in single "
                 f"support median {'n/a' if median is None else f'{median:.1f} N'}" + note, fontsize=10)
    ctx.save_figure(fig, "g1_walk_forces.png")
