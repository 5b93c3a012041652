"""Shared checks of the planner tests."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.planners import JointTrajectory


def _check_consistent(traj: JointTrajectory) -> float:
    """q and v agree by central differences; returns the max error [rad/s].

    The central difference errs by ``dt^2 / 6 |jerk|``; the jerk is estimated from differences
    of a, with 50 % slack plus round-off.
    """
    dt = traj.dt_s
    v_fd = (traj.q[2:] - traj.q[:-2]) / (2 * dt)
    err = float(np.max(np.abs(v_fd - traj.v[1:-1])))
    jerk = float(np.max(np.abs(np.diff(traj.a, axis=0)))) / dt
    assert err <= 1.5 * dt**2 / 6 * jerk + 1e-9 * max(1.0, float(np.max(np.abs(traj.v))))
    return err


@pytest.fixture(scope="session")
def check_consistent():
    """``check_consistent(traj) -> max error``: q and v agree by central differences."""
    return _check_consistent
