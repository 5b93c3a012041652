"""Whole-body inverse dynamics: a QP over accelerations and contact forces, torque output.

The tasks are the task layer's (:mod:`mbctl.control.tasks`), used at the acceleration level.
Walking (:mod:`mbctl.control.wbc.walking`) runs on the same QP: footsteps, a DCM plan, swing feet
and contact switches.
"""

from mbctl.control.wbc.config import WBCConfig, WBCSolution
from mbctl.control.wbc.contacts import ContactState, FootContact, foot_contact_from_model
from mbctl.control.wbc.controller import WholeBodyController
from mbctl.control.wbc.gait import GaitEvent
from mbctl.control.wbc.standing import Scheduled, Standing, standing_controller
from mbctl.control.wbc.step_adaptation import StepAdaptation, StepAdapter, StepTiming, dcm_tube
from mbctl.control.wbc.swing_task import SwingFootTask
from mbctl.control.wbc.walking import WalkingController, WalkingStatus
from mbctl.control.wbc.walking_config import WalkingConfig, quick_gait

__all__ = [
    "ContactState",
    "FootContact",
    "GaitEvent",
    "Scheduled",
    "Standing",
    "StepAdaptation",
    "StepAdapter",
    "StepTiming",
    "SwingFootTask",
    "WBCConfig",
    "WBCSolution",
    "WalkingConfig",
    "WalkingController",
    "WalkingStatus",
    "WholeBodyController",
    "dcm_tube",
    "foot_contact_from_model",
    "quick_gait",
    "standing_controller",
]
