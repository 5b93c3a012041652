"""Whole-body inverse dynamics: a QP over accelerations and contact forces, torque output."""

from mbctl.control.wbc.contacts import FootContact, foot_contact_from_model
from mbctl.control.wbc.controller import WBCConfig, WBCSolution, WholeBodyController
from mbctl.control.wbc.tasks import (
    AccelerationTask,
    AngularMomentumDamping,
    ComAcceleration,
    DynamicsState,
    FrameOrientationAcceleration,
    FramePoseAcceleration,
    FramePositionAcceleration,
    PostureAcceleration,
    TaskGains,
)

__all__ = [
    "AccelerationTask",
    "AngularMomentumDamping",
    "ComAcceleration",
    "DynamicsState",
    "FootContact",
    "FrameOrientationAcceleration",
    "FramePoseAcceleration",
    "FramePositionAcceleration",
    "PostureAcceleration",
    "TaskGains",
    "WBCConfig",
    "WBCSolution",
    "WholeBodyController",
    "foot_contact_from_model",
]
