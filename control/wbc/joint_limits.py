"""The whole-body QP's joint-limit bounds: acceleration bounds that stop each joint inside its range.

For every actuated 1-dof joint with finite limits, ``q + v T + vdot T^2 / 2`` stays within
``[q_min + margin, q_max - margin]`` over the horizon ``T`` (``WBCConfig.joint_limit_horizon_s``)::

    (q_min + margin - q - v T) 2 / T^2  <=  vdot_j  <=  (q_max - margin - q - v T) 2 / T^2

A joint heading for a limit must decelerate (its bound turns positive), at most by the cap ``A``
(``WBCConfig.joint_limit_max_accel_rad_s2``): the lower bound is capped at ``A`` and the upper
one at ``-A``, so that ``lb <= ub`` and the bounds stay feasible under the torque limits.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from mbctl.control.wbc.config import WBCConfig
from mbctl.robots.indexing import as_slice


class JointLimitBounds:
    """The joint-limit acceleration bounds of a model's actuated joints (see the module docstring).

    Args:
        model: The Pinocchio model.
        actuated_v: Tangent indices of the actuated dofs.

    Attributes:
        iv: (n,) the bounded joints' tangent indices (actuated 1-dof joints with finite limits).
        iq: (n,) their configuration indices.
        q_min, q_max: (n,) their limits [rad or m].
        index: ``iv`` as a slice when contiguous (indexing is then a view), else ``iv``.
        lower_scaled, upper_scaled: (n,) ``(q_min + margin) 2 / T^2`` and ``(q_max - margin) 2 / T^2``
            [rad/s^2 or m/s^2], the bounds' fixed part at the last :meth:`configure`.
    """

    def __init__(self, model: pin.Model, actuated_v: np.ndarray):
        iv, iq, lo, hi = [], [], [], []
        for j in range(1, model.njoints):
            joint = model.joints[j]
            if joint.nv != 1 or joint.nq != 1 or joint.idx_v not in actuated_v:
                continue
            q_lo = model.lowerPositionLimit[joint.idx_q]
            q_hi = model.upperPositionLimit[joint.idx_q]
            if np.isfinite(q_lo) and np.isfinite(q_hi) and q_hi > q_lo:
                iv.append(joint.idx_v)
                iq.append(joint.idx_q)
                lo.append(q_lo)
                hi.append(q_hi)
        self.iv, self.iq = np.array(iv, dtype=int), np.array(iq, dtype=int)
        self.q_min, self.q_max = np.array(lo), np.array(hi)
        self.index = as_slice(self.iv)
        self._nq, self._nv = model.nq, model.nv
        self._shift = np.zeros(len(iv))
        self.configure(WBCConfig())

    def __len__(self) -> int:
        """The number of bounded joints."""
        return len(self.iv)

    def configure(self, config: WBCConfig) -> None:
        """Derive the bounds' fixed parts from ``config`` (horizon, margin, cap)."""
        Th = config.joint_limit_horizon_s
        scale = 2.0 / Th**2
        self.lower_scaled = (self.q_min + config.joint_limit_margin_rad) * scale
        self.upper_scaled = (self.q_max - config.joint_limit_margin_rad) * scale
        self._cap = config.joint_limit_max_accel_rad_s2
        # the reach's part, -(q + v T) 2 / T^2, as one product with the state's [q; v] (one call
        # instead of three on slices)
        n, rows = len(self.iv), np.arange(len(self.iv))
        self._reach = np.zeros((n, self._nq + self._nv))
        self._reach[rows, self.iq] = -scale
        self._reach[rows, self._nq + self.iv] = -scale * Th

    def write(self, qv: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> None:
        """Write the bounds at ``qv = [q; v]`` (nq + nv,) into the entries ``iv`` of ``lb`` and ``ub``."""
        shift = self._shift  # -(q + v T) 2 / T^2: where the joints coast to in T
        np.dot(self._reach, qv, out=shift)
        index, cap = self.index, self._cap
        if isinstance(index, slice):  # views: written in place
            lo, hi = lb[index], ub[index]
            np.minimum(np.add(self.lower_scaled, shift, out=lo), cap, out=lo)
            np.maximum(np.add(self.upper_scaled, shift, out=hi), -cap, out=hi)
        else:
            lb[index] = np.minimum(self.lower_scaled + shift, cap)
            ub[index] = np.maximum(self.upper_scaled + shift, -cap)
