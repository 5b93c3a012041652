"""Whole-body IK backends by name: where the two backend modules meet (no import circle)."""

from __future__ import annotations

import numpy.typing as npt

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.mink_backend import MinkWholeBodyIK
from mbctl.control.ik.whole_body import QPWholeBodyIK, WholeBodyIK, WholeBodyIKConfig
from mbctl.robots.model_pair import Robot

#: Backend names accepted by :func:`make_whole_body_ik`.
BACKENDS = ("qp", "mink")

#: Backend name -> class.
BACKEND_CLASSES: dict[str, type[WholeBodyIK]] = {"qp": QPWholeBodyIK, "mink": MinkWholeBodyIK}


def make_whole_body_ik(
    backend: str,
    robot: Robot,
    config: WholeBodyIKConfig,
    q_ref: npt.ArrayLike,
    solver: str = "daqp",
) -> WholeBodyIK:
    """Build the task set ``config`` on ``backend`` ("qp" or "mink").

    Args:
        backend: "qp" (our Pinocchio QP) or "mink".
        robot: The model pair.
        config: Task set, weights and limits.
        q_ref: Start configuration (nq,), Pinocchio convention: the first targets.
        solver: qpsolvers backend name.

    Raises:
        IKSetupError: Unknown backend (the message names the alternatives), or a bad task set.
    """
    if backend not in BACKEND_CLASSES:
        raise IKSetupError(f"IK backend {backend!r} is unknown; choose one of {', '.join(BACKENDS)}")
    return BACKEND_CLASSES[backend](robot, config, q_ref, solver)
