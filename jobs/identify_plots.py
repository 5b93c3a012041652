"""The identify job's validation outputs: torques per joint, measured against both models' predictions."""

from __future__ import annotations

import numpy as np

from mbctl.jobs.plots import new_figure
from mbctl.jobs.runner import RunContext
from mbctl.robots.identification import Identification

#: Joints drawn in the plot at most (those the nominal model predicts worst).
MAX_PANELS = 8


def stream_validation(ctx: RunContext, ident: Identification) -> None:
    """``identify.csv``: time, then per joint the measured torque and both predictions [N m]."""
    nom, idn = ident.nominal_prediction, ident.identified_prediction
    header = ["time_s"]
    for j in nom.joints:
        header += [f"tau_{j}_measured_N_m", f"tau_{j}_nominal_N_m", f"tau_{j}_identified_N_m"]
    csv = ctx.open_csv(header)
    for k in range(len(nom.t_s)):
        row = [float(nom.t_s[k])]
        for i in range(len(nom.joints)):
            row += [nom.measured[k, i], nom.predicted[k, i], idn.predicted[k, i]]
        csv.write(row)


def validation_plot(ctx: RunContext, ident: Identification) -> None:
    """Measured torque (black) and both models' predictions on the validation part, per joint.

    The joints the nominal model predicts worst are drawn (at most :data:`MAX_PANELS`); each
    panel's title gives both RMS errors.
    """
    nom, idn = ident.nominal_prediction, ident.identified_prediction
    err_nom = np.sqrt(np.mean((nom.measured - nom.predicted) ** 2, axis=0))
    err_id = np.sqrt(np.mean((idn.measured - idn.predicted) ** 2, axis=0))
    order = np.argsort(-err_nom)[:MAX_PANELS]
    cols = 2 if len(order) > 1 else 1
    rows = int(np.ceil(len(order) / cols))
    fig, axes = new_figure(rows, cols, (13.0, 2.6 * rows + 0.8), layout="constrained")
    t = nom.t_s
    # samples of several logs are concatenated: draw each log's stretch as its own line
    breaks = np.flatnonzero(np.diff(t) <= 0) + 1
    for n_ax, i in enumerate(order):
        ax = axes[n_ax // cols][n_ax % cols]
        for seg in np.split(np.arange(len(t)), breaks):
            ax.plot(t[seg], nom.measured[seg, i], color="k", lw=1.4)
            ax.plot(t[seg], nom.predicted[seg, i], color="tab:red", lw=1.0, ls="--")
            ax.plot(t[seg], idn.predicted[seg, i], color="tab:blue", lw=1.0)
        ax.set_title(f"{nom.joints[i]}: RMSE nominal {err_nom[i]:.3g}, identified {err_id[i]:.3g} N m",
                     fontsize=9)
        ax.set_ylabel("torque (N m)")
        ax.grid(True, alpha=0.3)
    for n_ax in range(len(order), rows * cols):
        axes[n_ax // cols][n_ax % cols].set_visible(False)
    for c in range(cols):
        axes[rows - 1][c].set_xlabel("time (s)")
    axes[0][0].plot([], [], color="k", lw=1.4, label="measured")
    axes[0][0].plot([], [], color="tab:red", ls="--", label="nominal model")
    axes[0][0].plot([], [], color="tab:blue", label="identified model")
    axes[0][0].legend(fontsize=8, loc="upper right")
    contacts = {"none": "", "projected": " (contact wrench eliminated by projection)",
                "measured": " (measured contact wrench)"}[ident.contact]
    fig.suptitle(f"validation (last part of each log, never used to identify): torque predicted vs measured"
                 f"{contacts}; all joints: RMSE nominal {nom.rmse():.3g}, identified {idn.rmse():.3g} N m",
                 fontsize=10)
    ctx.save_figure(fig, "identify.png")
