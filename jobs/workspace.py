"""The ``mbctl workspace`` job: the 2-link arm's reachable annulus and a sampled workspace plot.

Only the planar 2-link arm is supported (``SUPPORTED_ROBOTS``): the annulus
``|l1 - l2| <= |p_WS - p_WO| <= l1 + l2`` is its analytic geometry
(``mbctl.control.ik.two_link.TwoLinkArm``). The run folder gets ``workspace.png`` (site positions
over an ``n x n`` grid of joint angles inside the joint limits, with the r_min and r_max circles)
and the runner's ``report.json`` (``r_min_m``, ``r_max_m``, link lengths).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib import colormaps

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.two_link import TwoLinkArm
from mbctl.jobs.choices import TWO_LINK_ROBOTS
from mbctl.jobs.plots import new_figure
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.limits import MAX_WORKSPACE_SAMPLES, check_limit
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot

#: Robots ``mbctl workspace`` knows the workspace of (registry names of the 2-link arm).
SUPPORTED_ROBOTS = TWO_LINK_ROBOTS


@dataclass(frozen=True)
class WorkspaceParams:
    """What ``mbctl workspace`` runs.

    Attributes:
        robot: A registry name in ``SUPPORTED_ROBOTS``.
        samples: Samples per joint of the joint-angle grid (>= 2).
    """

    robot: str = "two_link"
    samples: int = 121

    def __post_init__(self) -> None:
        if self.robot not in SUPPORTED_ROBOTS:
            raise IKSetupError(
                f"mbctl workspace supports only the planar 2-link arm ({', '.join(SUPPORTED_ROBOTS)}); "
                f"got {self.robot!r}. For other robots use `mbctl ik` to test reachability of a target."
            )
        if int(self.samples) < 2:
            raise IKSetupError(f"samples must be >= 2 per joint; got {self.samples!r}")
        check_limit("--samples", int(self.samples), MAX_WORKSPACE_SAMPLES,
                    advice="the plot draws a samples x samples grid; a few hundred is plenty")


def sample_workspace(arm: TwoLinkArm, robot: Robot | None = None, n: int = 121) -> np.ndarray:
    """Site positions (n*n, 2) [m], world x-y, over an ``n x n`` grid of joint angles.

    Args:
        arm: Arm geometry.
        robot: If given, finite Pinocchio joint limits bound the grid; otherwise (-pi, pi].
        n: Samples per joint (>= 2).

    Raises:
        IKSetupError: ``n`` < 2.
    """
    if int(n) < 2:
        raise IKSetupError(f"n must be >= 2 samples per joint; got {n!r}")
    lo = np.full(2, -math.pi)
    hi = np.full(2, math.pi)
    if robot is not None:
        lo = np.maximum(lo, robot.pin_model.lowerPositionLimit)
        hi = np.minimum(hi, robot.pin_model.upperPositionLimit)
    g1, g2 = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    q = np.column_stack([g1.ravel(), g2.ravel()])
    return np.array([arm.forward_kinematics(qi) for qi in q])


def plot_workspace(arm: TwoLinkArm, points: np.ndarray) -> object:
    """A figure of the sampled site positions (k, 2) [m] with the r_min and r_max circles.

    The samples are shown as a density (hexagonal bins, log colour scale: a uniform joint grid
    crowds the shoulder), not as dots: a regular grid drawn dot by dot makes moire rings. The inner
    circle (r_min, often a few mm) is shown again in an inset around the shoulder, in mm.
    """
    fig, axes = new_figure(1, 1, (6.0, 5.6))
    ax = axes[0, 0]
    x, y = points[:, 0], points[:, 1]
    bins = ax.hexbin(x, y, gridsize=25, cmap="Blues", mincnt=1, linewidths=0.2, bins="log")
    fig.colorbar(bins, ax=ax, shrink=0.8, label="joint-grid samples per bin (log scale)")
    t = np.linspace(0.0, 2.0 * math.pi, 361)
    circles = ((arm.r_max, "-", "r_max"), (arm.r_min, "--", "r_min"))
    for radius, style, label in circles:
        ax.plot(arm.base_x + radius * np.cos(t), arm.base_y + radius * np.sin(t), style, color="k",
                label=f"{label} = {radius * 1e3:.4g} mm")
    ax.plot(arm.base_x, arm.base_y, "+", color="crimson", ms=10, label="shoulder")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"2-link workspace (l1 = {arm.link1_length:.4g} m, l2 = {arm.link2_length:.4g} m)")
    ax.legend(loc="upper left", fontsize="small", framealpha=0.9)
    zoom = max(3.0 * arm.r_min, 0.02)  # the inset's half width [m]
    if zoom < 0.25 * arm.r_max:
        inset = ax.inset_axes((0.765, 0.01, 0.225, 0.225))  # the corner the circle leaves free
        inset.set_facecolor(colormaps["Blues"](0.35))  # reachable
        inner = arm.r_min * 1e3
        inset.fill(inner * np.cos(t), inner * np.sin(t), facecolor="white", edgecolor="k", ls="--",
                   hatch="///", label="unreachable")
        inset.plot(0, 0, "+", color="crimson", ms=8)
        lim = zoom * 1e3
        inset.set_xlim(-lim, lim)
        inset.set_ylim(-lim, lim)
        inset.set_aspect("equal")
        inset.set_xticks([])
        inset.set_yticks([])
        inset.text(0, 0.62 * lim, f"+/-{lim:.3g} mm", ha="center", fontsize="x-small")
        inset.text(0, -0.85 * lim, f"r_min {inner:.3g} mm", ha="center", fontsize="x-small")
        ax.indicate_inset(
            (arm.base_x - zoom, arm.base_y - zoom, 2 * zoom, 2 * zoom), inset_ax=inset, edgecolor="0.4")
    fig.tight_layout()
    return fig


def prepare(params: WorkspaceParams) -> Work:
    """Load the arm and read its geometry (no output yet)."""
    robot = load_robot(params.robot)
    arm = TwoLinkArm.from_robot(robot)

    def work(ctx: RunContext) -> Outcome:
        points = sample_workspace(arm, robot, params.samples)
        ctx.values.update({"link1_length_m": arm.link1_length, "link2_length_m": arm.link2_length,
                           "r_min_m": arm.r_min, "r_max_m": arm.r_max, "samples": len(points)})
        ctx.save_figure(plot_workspace(arm, points), "workspace.png")
        return Outcome(True, (
            f"links {arm.link1_length:.4f} m and {arm.link2_length:.4f} m (to the site); reachable "
            f"annulus r_min = {arm.r_min:.4f} m, r_max = {arm.r_max:.4f} m around the shoulder",
        ))

    return work


#: The ``mbctl workspace`` job.
WORKSPACE = Job("workspace", prepare)
