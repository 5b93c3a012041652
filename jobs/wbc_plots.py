"""Plots of ``mbctl g1-wbc``: CoM tracking, and the contact-level cross-check (QP vs MuJoCo)."""

from __future__ import annotations

from typing import Any

from mbctl.jobs.log_sums import rows_note
from mbctl.jobs.plots import new_figure
from mbctl.jobs.runner import RunContext
from mbctl.jobs.wbc_log import WBCLog
from mbctl.robots.g1 import FEET


def wbc_plots(ctx: RunContext, log: WBCLog, params: Any, values: dict[str, Any]) -> None:
    """Save ``g1_wbc.png`` and ``g1_wbc_contacts.png``.

    The first: CoM reference and plant, the CoM error, the total normal force. The second, per
    foot: normal force, tangential force, CoP x and y, QP dashed over MuJoCo solid. The curves are
    the log's kept rows (every ``stride``-th cycle of a long run, said in the titles).
    """
    r = log.record()
    if not len(r.t):
        return
    t, com, ref, fz_qp, fz_mj = r.t, r.com, r.com_ref, r.fz_qp, r.fz_mj
    note = rows_note(log.stride, log.k)
    source = "MuJoCo" if log.monitor is not None else "truth log" if log.com_from_truth else "estimated"
    fig, axes = new_figure(2, 2, (13.0, 7.5), layout="constrained")
    for i, (axis, color) in enumerate(zip("xyz", ("C0", "C1", "C2"), strict=True)):
        ax = axes[0][0] if i < 2 else axes[0][1]
        ax.plot(r.t_plant, com[:, i] * 1e3, color=color, lw=1.3, label=f"CoM {axis} ({source})")
        ax.plot(t, ref[:, i] * 1e3, color=color, lw=1.0, ls="--", label=f"CoM {axis} reference")
    axes[0][0].set_ylabel("CoM x, y (mm)")
    axes[0][1].set_ylabel("CoM z (mm)")
    t_err, err = log.com_error_rows()
    axes[1][0].plot(t_err, err * 1e3, color="k", lw=1.0)
    axes[1][0].set_ylabel("|CoM - reference| (mm)")
    axes[1][0].set_title(f"CoM error, RMS {values['com_error_rms_m'] * 1e3:.2f} mm", fontsize=9)
    axes[1][1].plot(t, fz_mj.sum(1), color="C3", lw=1.3, label="sum f_z MuJoCo")
    axes[1][1].plot(t, fz_qp.sum(1), color="k", lw=1.0, ls="--", label="sum f_z QP")
    axes[1][1].set_ylabel("total normal force (N)")
    axes[1][1].set_title(f"median |QP - MuJoCo| in stance: {values['contact_force_rel_error'] * 100:.2f} % "
                         "of m g", fontsize=9)
    for ax in (axes[0][0], axes[0][1], axes[1][1]):
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    for row in axes:
        for ax in row:
            ax.grid(True, alpha=0.3)
            ax.set_xlabel("time (s)")
    verdict = "FELL" if values["fell"] else "stood"
    fig.suptitle(f"G1 whole-body inverse dynamics, {params.scenario}: {verdict}, controller "
                 f"{values['controller_time_median_us']:.0f} us median" + note)
    ctx.save_figure(fig, "g1_wbc.png")

    ft_qp, ft_mj, cop_qp, cop_mj = r.ft_qp, r.ft_mj, r.cop_qp, r.cop_mj
    fig, axes = new_figure(len(FEET), 3, (15.0, 3.4 * len(FEET) + 0.8), layout="constrained")
    for i, foot in enumerate(FEET):
        a_n, a_t, a_c = axes[i]
        a_n.plot(t, fz_mj[:, i], color="C3", lw=1.3, label="MuJoCo")
        a_n.plot(t, fz_qp[:, i], color="k", lw=1.0, ls="--", label="QP")
        a_n.set_ylabel(f"{foot}\nnormal force (N)")
        a_t.plot(t, ft_mj[:, i], color="C3", lw=1.3, label="MuJoCo")
        a_t.plot(t, ft_qp[:, i], color="k", lw=1.0, ls="--", label="QP")
        a_t.set_ylabel("tangential force (N)")
        for j, (axis, color) in enumerate(zip("xy", ("C0", "C1"), strict=True)):
            a_c.plot(t, cop_mj[:, i, j] * 1e3, color=color, lw=1.3, label=f"CoP {axis} MuJoCo")
            a_c.plot(t, cop_qp[:, i, j] * 1e3, color="k" if j == 0 else "0.45", lw=1.0, ls="--",
                     label=f"CoP {axis} QP")
        a_c.set_ylabel("centre of pressure (mm, world)")
        for ax in (a_n, a_t, a_c):
            ax.grid(True, alpha=0.3)
            ax.set_xlabel("time (s)")
        a_t.legend(fontsize=8, loc="upper right")
        a_c.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle("contact forces predicted by the QP (dashed) and measured in MuJoCo (solid: the forces "
                 "its constraint solver applied on the foot geoms)" + note)
    ctx.save_figure(fig, "g1_wbc_contacts.png")
