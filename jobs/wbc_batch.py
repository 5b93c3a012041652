"""A batch of g1-wbc cycles as arrays: the QP's and MuJoCo's per-foot forces and CoPs, and the slips.

:class:`~mbctl.jobs.wbc_log.WBCLog` keeps each cycle's own objects and records them a batch at a
time; these functions turn a batch into columns with one numpy call per quantity instead of a
few hundred float operations per cycle (the per-cycle version cost about 18 us a cycle).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mbctl.control.wbc import WBCSolution

#: Below this normal force [N] a foot's QP CoP is not defined (NaN).
QP_MIN_FZ_N = 1e-6
#: Below this normal force [N] a foot's measured CoP is not defined (NaN).
MJ_MIN_FZ_N = 1e-9


def qp_feet(sols: Sequence[WBCSolution], feet: Sequence[str]) -> np.ndarray:
    """Per cycle and foot, the QP's prediction: normal, tangential force [N], CoP x, y [m] in W (B, f, 4).

    Each foot's force is the sum of its points' forces turned into W (the points' forces are in the
    foot's frame F); its CoP is that of the points' world-z forces at their positions, moved to W
    (NaN below :data:`QP_MIN_FZ_N`). Cycles are taken in runs that share the contact layout.
    """
    out = np.empty((len(sols), len(feet), 4))
    start = 0
    while start < len(sols):
        first = sols[start]
        end = start + 1
        while end < len(sols) and sols[end].points_F is first.points_F \
                and sols[end].force_slices is first.force_slices:
            end += 1
        run = sols[start:end]
        forces = np.array([s.forces for s in run])
        for i, f in enumerate(feet):
            points = first.points_F[f]
            F = forces[:, first.force_slices[f]].reshape(len(run), len(points), 3)
            poses = [s.foot_poses_W[f] for s in run]
            R = np.array([p.rotation for p in poses])
            o = np.array([p.translation for p in poses])
            total = np.einsum("bij,bj->bi", R, F.sum(axis=1))
            wz = np.einsum("bj,bpj->bp", R[:, 2], F)  # each point's force along W's z
            moment = np.einsum("bij,bj->bi", R, wz @ points)
            fz = total[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                cop = moment[:, :2] / fz[:, None] + o[:, :2]
            cop[fz <= QP_MIN_FZ_N] = np.nan
            out[start:end, i] = np.column_stack([fz, np.hypot(total[:, 0], total[:, 1]), cop])
        start = end
    return out


def plant_feet(nets: np.ndarray, groups: Sequence[int]) -> np.ndarray:
    """Per cycle and group, what MuJoCo applied: fx, fy, fz [N] in W, CoP x, y [m] (B, g, 5).

    Args:
        nets: Each cycle's :meth:`ContactSensor.net <mbctl.sim.contacts.ContactSensor.net>` (B, 10 n).
        groups: The groups wanted, by index (e.g. the feet among the monitor's groups).
    """
    out = np.empty((len(nets), len(groups), 5))
    for i, g in enumerate(groups):
        net = nets[:, 10 * g:10 * g + 10]  # what the group exerts: minus the force on it
        fz = -net[:, 3]
        out[:, i, :3] = -net[:, 1:4]
        with np.errstate(divide="ignore", invalid="ignore"):
            # fz * CoP = fz p + (horizontal moment about p) x z (MuJoCo's sensor layout)
            out[:, i, 3] = (net[:, 5] + fz * net[:, 7]) / fz
            out[:, i, 4] = (-net[:, 4] + fz * net[:, 8]) / fz
        out[fz <= MJ_MIN_FZ_N, i, 3:] = np.nan
    return out


def slips(counts: np.ndarray, xy: np.ndarray, home: tuple[float, float] | None
          ) -> tuple[np.ndarray, tuple[float, float] | None]:
    """A foot's slip over a batch: its horizontal drift [m] from where it last started to support.

    Args:
        counts: Whether the foot supports in each cycle (B,) (a cycle that does not resets its home).
        xy: The foot's position (B, 2) [m] in W.
        home: Where it started to support before the batch (None: nowhere yet).

    Returns:
        The slip of each cycle (B,) (0 where it does not support), and the home after the batch.
    """
    b = len(counts)
    idx = np.where(counts, -1, np.arange(b))
    last_reset = np.maximum.accumulate(idx)  # the last cycle, up to each, that did not support
    homes = xy[np.maximum(last_reset, 0)].copy()
    before = last_reset < 0  # supporting since before the batch (or since its first cycle)
    if before.any():
        homes[before] = home if home is not None else xy[0]
    slip = np.where(counts, np.hypot(*(xy - homes).T), 0.0)
    after = homes[-1] if counts[-1] else xy[-1]
    return slip, (float(after[0]), float(after[1]))
