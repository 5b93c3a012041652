"""Differential inverse kinematics: state, tasks, limits, the QP, whole-body backends, 2-link IK."""
