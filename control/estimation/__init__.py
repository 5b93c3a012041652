"""State estimation: what a robot does not measure (its base's position and velocity), from what it does."""

from mbctl.control.estimation.exceptions import EstimatorError
from mbctl.control.estimation.leg_kinematics import LegKinematicsEstimator, LegKinematicsNoise

__all__ = ["EstimatorError", "LegKinematicsEstimator", "LegKinematicsNoise"]
