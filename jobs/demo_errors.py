"""The demo's tracking errors, summed over every cycle as the loop runs (its log may keep fewer rows)."""

from __future__ import annotations

import numpy as np

from mbctl.jobs.recording import PlantSite
from mbctl.robots.interface import RobotState


class SquareErrors:
    """Every cycle's Cartesian error (and a task-space controller's joint error), summed as the loop runs.

    Args:
        site: The end effector on the plant.
        p_ref: Reference positions (N, 2) [m] of each cycle.
        q_ref: Joint references (N, n) [rad] of each cycle for the joint error, or None.
        idx_q: The controller's joints' indices in q (n,).
        period_s: The control period [s].
        t_start_s: The plant's time at the first cycle [s].
    """

    def __init__(self, site: PlantSite, p_ref: np.ndarray, q_ref: np.ndarray | None, idx_q: np.ndarray,
                 period_s: float, t_start_s: float):
        self.site, self.p_ref, self.q_ref, self.idx_q = site, p_ref, q_ref, idx_q
        self.period_s, self.t_start_s = period_s, t_start_s
        self.count, self.sum_sq, self.max, self.joint_sum_sq = 0, 0.0, 0.0, 0.0

    def __call__(self, state: RobotState) -> tuple[int, np.ndarray, float]:
        """Add the cycle of ``state``; its index, end-effector position (3,) [m] and error [m]."""
        k = min(int(round((state.time_s - self.t_start_s) / self.period_s)), len(self.p_ref) - 1)
        p = self.site(state.q)
        e = float(np.hypot(*(self.p_ref[k] - p[:2])))
        self.count += 1
        self.sum_sq += e * e
        self.max = max(self.max, e)
        if self.q_ref is not None:
            d = self.q_ref[k] - state.q[self.idx_q]
            self.joint_sum_sq += float(d @ d)
        return k, p, e

    def rms(self) -> float:
        """RMS Cartesian error [m] over every cycle."""
        return float(np.sqrt(self.sum_sq / self.count))

    def joint_rms(self) -> float:
        """RMS joint error [rad] over every cycle and joint (with ``q_ref``)."""
        return float(np.sqrt(self.joint_sum_sq / (self.count * len(self.idx_q))))
