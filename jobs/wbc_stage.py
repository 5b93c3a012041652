"""A g1-wbc cycle's values staged for its log (:class:`~mbctl.jobs.wbc_log.WBCLog`): one row a cycle.

:meth:`WBCLog.on_step <mbctl.jobs.wbc_log.WBCLog.on_step>` copies each cycle's values here as the
cycle ends, a few row stores while they are still in the CPU's caches; the log records a batch of
rows at a time with one numpy call per quantity.
"""

from __future__ import annotations

import numpy as np

from mbctl.control.wbc import WBCSolution
from mbctl.control.wbc.config import foot_totals_and_cops_W
from mbctl.robots.g1 import FEET
from mbctl.sim.monitor import PlantMonitor

#: The columns of :class:`WBCStage`'s scalars: the state's time, the plant's, the physics step's and the
#: controller's and QP's wall times [s], the fallback flag, each foot's (active, weight), the cycle's end.
S_T_PLANT, S_PHYSICS, S_CTRL, S_QP, S_FALLBACK = 1, 2, 3, 4, 5
S_FEET = slice(6, 6 + 2 * len(FEET))
S_NOW = 6 + 2 * len(FEET)


class WBCStage:
    """A batch's staging arrays (:meth:`~mbctl.jobs.wbc_log.WBCLog.on_step`): one row a cycle.

    Sized by the first cycle: its state, command and solution (the controller's layout: its feet's
    force slices, points and poses, fixed with it) and the monitor (sites, contact groups).
    """

    def __init__(self, batch: int, sol: WBCSolution, nq: int, nt: int, monitor: PlantMonitor | None):
        self.force_slices, self.points_F = sol.force_slices, sol.points_F
        self.order = list(sol.force_slices)  # the poses' order
        self.scalars = np.zeros((batch, S_NOW + 1))
        self.q, self.tau = np.zeros((batch, nq)), np.zeros((batch, nt))
        self.ref, self.com, self.push = np.zeros((batch, 3)), np.zeros((batch, 3)), np.zeros((batch, 2))
        self.forces = np.zeros((batch, sol.forces.size))
        self.X = np.zeros((batch, len(sol.foot_X_W), 4, 4))
        sites = len(monitor.site_names) if monitor is not None else 0
        self.sites = np.zeros((batch, sites, 3))
        # each contact group's net contact, 10 numbers (ContactSensor.net's layout, for sums_block)
        self.net = np.zeros((batch, 10 * len(monitor.group_names) if monitor is not None else 0))

    def qp_feet(self, b: int) -> np.ndarray:
        """Per staged cycle (the first ``b``) and foot (FEET order), the QP's prediction (b, n_feet, 4).

        The normal and tangential force [N] and the CoP's x, y [m] in W
        (:func:`~mbctl.control.wbc.config.foot_totals_and_cops_W` over the batch), in the
        controller's layout (``force_slices``, ``points_F``: built once with it).
        """
        forces, X = self.forces[:b], self.X[:b]
        out = np.empty((b, len(FEET), 4))
        for j, f in enumerate(FEET):
            total, cop = foot_totals_and_cops_W(forces[:, self.force_slices[f]].reshape(b, -1, 3),
                                                X[:, self.order.index(f)], self.points_F[f])
            out[:, j, 0] = total[:, 2]
            out[:, j, 1] = np.hypot(total[:, 0], total[:, 1])
            out[:, j, 2:] = cop[:, :2]
        return out
