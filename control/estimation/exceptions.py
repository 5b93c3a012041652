"""Errors of the state estimators."""

from __future__ import annotations

from mbctl.control.exceptions import ControlError


class EstimatorError(ControlError):
    """An estimator that cannot be built (no feet, unknown frames) or cannot go on (diverged)."""
