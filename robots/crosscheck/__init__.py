"""Cross-validation of the Pinocchio model against the MuJoCo plant.

Modules: ``tolerances`` (pass criteria), ``sampling`` (the states), ``plant`` (MuJoCo's private
comparison copy and feature audit), ``evaluate`` (both engines over the states, ``crosscheck``),
``report`` (the result).
"""

from mbctl.robots.crosscheck.evaluate import crosscheck
from mbctl.robots.crosscheck.exceptions import CrossCheckError
from mbctl.robots.crosscheck.report import FeatureNote, QuantityResult, Report
from mbctl.robots.crosscheck.sampling import Sampling
from mbctl.robots.crosscheck.tolerances import TOLERANCES, Tolerance

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
