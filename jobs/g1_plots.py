"""The G1 jobs' plots (``g1-stand``, ``g1-track``, ``g1-arm-pd``).

Plots: reference dashed, plant solid; at most eight labelled traces per panel. The tracking jobs
draw one row per limb that moves, coloured by the joint's role in the limb (the knee has one
colour in both legs); the standing job draws the pelvis height change [mm] on its own panel and
the joints that moved most, with mirror pairs that move identically drawn once.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbctl.control.loop import RunLog
from mbctl.jobs.log_sums import rows_note
from mbctl.jobs.plots import coincident_groups, joint_colors, most_moved, new_figure, tracking_panels
from mbctl.jobs.runner import RunContext
from mbctl.robots.g1 import joint_role, limb_of

#: A limb whose reference moves less than this [rad] is left out of the tracking plots.
MOVED_RAD = 1e-6


def limb_rows(joints: tuple[str, ...], reference: np.ndarray,
              per_row: int = 8) -> list[tuple[str, list[int]]]:
    """Columns of ``reference`` (N, n) grouped by limb, limbs whose reference moves only.

    Args:
        joints: Names of the columns (n).
        reference: Reference angles (N, n) [rad].
        per_row: At most this many joints per limb (the ones that moved most).

    Returns:
        (limb, column indices) in the order the limbs first appear in ``joints``; every limb when
        no reference moves (a run shorter than the first motion).
    """
    limbs: dict[str, list[int]] = {}
    for i, name in enumerate(joints):
        limbs.setdefault(limb_of(name), []).append(i)
    rows = []
    for limb, idx in limbs.items():
        if len(idx) > per_row:
            idx = sorted(idx[k] for k in most_moved(reference[:, idx], per_row))
        rows.append((limb, idx))
    moved = [(limb, idx) for limb, idx in rows if np.ptp(reference[:, idx]) > MOVED_RAD]
    return moved or rows


def held_joints_panel(ax: Any, t_s: np.ndarray, deviation: np.ndarray, joints: tuple[str, ...],
                      also_coincide: tuple[np.ndarray, ...] = (),
                      k: int = 8) -> tuple[list[list[int]], list[Any]]:
    """Draw the ``k`` joints that moved most from a held pose, q - q_held [mrad].

    Mirror pairs that move identically (in ``deviation`` and every ``also_coincide`` signal)
    share one trace and one label, so every label names a line the reader can see.

    Returns:
        The groups of columns drawn and their colours.
    """
    candidates = most_moved(deviation, 2 * k)
    groups = coincident_groups((deviation, *also_coincide), candidates)[:k]
    labels = [" = ".join(joints[i].removesuffix("_joint") for i in g[:2])
              + (f" (+ {len(g) - 2} more)" if len(g) > 2 else "") for g in groups]
    colors = list(joint_colors(labels).values())
    ax.axhline(0.0, ls="--", lw=0.8, color="k", label="held pose (reference)")
    for g, label, color in zip(groups, labels, colors, strict=True):
        ax.plot(t_s, deviation[:, g[0]] * 1e3, lw=1.2, color=color, label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("q - q_held (mrad)")
    ax.grid(True, alpha=0.3)
    return groups, colors


def pelvis_panel(ax: Any, t_s: np.ndarray, dz_m: np.ndarray, max_m: float, bound_m: float) -> None:
    """Pelvis height change [mm] over time; ``max_m`` [m] is the run's value (final state included).

    ``bound_m`` [m]: the change a standing job must stay within, named in the title.
    """
    ax.plot(t_s, dz_m * 1e3, color="k", lw=1.2)
    ax.axhline(0.0, ls="--", lw=0.8, color="0.4")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("pelvis height - keyframe (mm)")
    ax.set_title(f"pelvis height change (max |change| {max_m * 1e3:.2f} mm; "
                 f"bound {bound_m * 1e3:g} mm)", fontsize=9)
    ax.grid(True, alpha=0.3)


def tracking_plot(ctx: RunContext, name: str, log: RunLog, joints: tuple[str, ...], err: np.ndarray,
                  title: str, body: tuple[np.ndarray, np.ndarray, tuple[str, ...]] | None = None, *,
                  bound_m: float) -> None:
    """One row per limb that moves: angles (plant solid, reference dashed) and errors in mrad.

    Colours follow the joint's role in its limb (the knee has one colour in both legs). With
    ``body`` = (pelvis height change (N,) [m], deviation of the other joints from their held
    targets (N, m) [rad], their names), a last row shows how the rest of the robot held still
    (``bound_m`` [m]: the pelvis bound, named in its panel).
    """
    q = log.reference - err
    t = log.row_time_s
    limbs = limb_rows(joints, log.reference)
    n_rows = len(limbs) + (body is not None)
    fig, axes = new_figure(n_rows, 2, (13.0, 2.9 * n_rows + 0.7), layout="constrained")
    for r, (limb, idx) in enumerate(limbs):
        roles = [joint_role(joints[i]) for i in idx]
        colors = joint_colors(roles)
        tracking_panels(axes[r][0], axes[r][1], t, log.reference[:, idx], q[:, idx], roles,
                        [colors[x] for x in roles], limb)
    if body is not None:
        dz, deviation, others = body
        pelvis_panel(axes[-1][0], t, dz, ctx.values["pelvis_max_deviation_m"], bound_m)
        groups, _ = held_joints_panel(axes[-1][1], t, deviation, others)
        axes[-1][1].set_title(f"the {len(groups)} other joints that moved most from the keyframe",
                              fontsize=9)
        axes[-1][1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(title + _rows_note(log))
    ctx.save_figure(fig, f"{name}.png")


def stand_plot(ctx: RunContext, log: RunLog, dz_m: np.ndarray, deviation: np.ndarray,
               joints: tuple[str, ...], omega_rad_s: float, zeta: float, bound_m: float) -> None:
    """Pelvis height change [mm] on its own panel, then the joints that moved most.

    The joints' deviation from the keyframe [mrad] and their torques [N m] share one colour per
    joint. ``omega_rad_s`` [rad/s] and ``zeta`` are the gains' (for the title), ``bound_m`` [m]
    the pelvis bound.
    """
    fig, axes = new_figure(1, 3, (17.0, 5.0), layout="constrained")
    ax_z, ax_q, ax_tau = axes[0]
    max_m = ctx.values["pelvis_max_deviation_m"]
    t = log.row_time_s
    pelvis_panel(ax_z, t, dz_m, max_m, bound_m)
    groups, colors = held_joints_panel(ax_q, t, deviation, joints, (log.command,))
    ax_q.set_title(f"the {len(groups)} joints that moved most from the keyframe", fontsize=9)
    for g, color in zip(groups, colors, strict=True):
        ax_tau.plot(t, log.command[:, g[0]], lw=1.2, color=color)
    ax_tau.set_xlabel("time (s)")
    ax_tau.set_ylabel("joint torque (N m)")
    ax_tau.set_title("their torques (PD + gravity), same colours", fontsize=9)
    ax_tau.grid(True, alpha=0.3)
    handles, labels = ax_q.get_legend_handles_labels()
    ax_tau.legend(handles, labels, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(f"G1 standing, PD + gravity in torque mode (omega {omega_rad_s:g} rad/s, "
                 f"zeta {zeta:g}): max pelvis height change {max_m * 1e3:.2f} mm" + _rows_note(log))
    ctx.save_figure(fig, "g1_stand.png")


def _rows_note(log: RunLog) -> str:
    """The title's note on the loop log's kept rows (:func:`mbctl.jobs.log_sums.rows_note`)."""
    return rows_note(log.stride, log.cycles)
