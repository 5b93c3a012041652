"""Cross-validation of the Pinocchio model against the MuJoCo plant."""

from mbctl.robots.crosscheck.evaluate import (
    TOLERANCES,
    CrossCheckError,
    Sampling,
    Tolerance,
    crosscheck,
)
from mbctl.robots.crosscheck.report import FeatureNote, QuantityResult, Report

__all__ = [
    "TOLERANCES",
    "CrossCheckError",
    "FeatureNote",
    "QuantityResult",
    "Report",
    "Sampling",
    "Tolerance",
    "crosscheck",
]
