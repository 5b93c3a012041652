"""Whole-body inverse dynamics: a QP over accelerations and contact forces, torque output.

The tasks are the task layer's (:mod:`mbctl.control.tasks`), used at the acceleration level.
"""

from mbctl.control.wbc.config import WBCConfig, WBCSolution
from mbctl.control.wbc.contacts import ContactState, FootContact, foot_contact_from_model
from mbctl.control.wbc.controller import WholeBodyController
from mbctl.control.wbc.standing import Scheduled, Standing, standing_controller

__all__ = [
    "ContactState",
    "FootContact",
    "Scheduled",
    "Standing",
    "WBCConfig",
    "WBCSolution",
    "WholeBodyController",
    "foot_contact_from_model",
    "standing_controller",
]
