"""The choices the command line lists in its help: controllers, scenarios, robots, sweepable jobs.

Kept free of heavy imports (no MuJoCo, Pinocchio, numpy), so ``mbctl --help`` and every command's
help are shown without loading the engines: the CLI imports a job only when its command runs.
The job modules take these names from here; ``tests/cli/test_help.py`` checks that the g1-wbc
job and the sweep catalog agree with them.
"""

from __future__ import annotations

#: ``mbctl demo --controller``: joint PD, PD + gravity, computed torque, task-space computed torque.
CONTROLLERS = ("pd", "pd_gravity", "ct", "task_ct")

#: The robots the 2-link arm's jobs (``verify``, ``workspace``) are written for.
TWO_LINK_ROBOTS = ("two_link", "two_link_torque")

#: ``mbctl g1-wbc SCENARIO``.
WBC_SCENARIOS = ("stand", "squat", "one-foot", "reach", "push")

#: Default simulated time [s] per g1-wbc scenario.
WBC_DEFAULT_DURATION_S = {"stand": 10.0, "squat": 10.0, "one-foot": 14.0, "reach": 8.0, "push": 17.0}

#: ``mbctl serve --start``: the G1's initial pose.
SERVE_STARTS = ("stand", "crouched")

#: The jobs ``mbctl sweep`` runs (``mbctl.jobs.catalog.CATALOG``), in its order.
SWEEP_JOBS = ("demo", "joint-step", "g1-stand", "g1-track", "g1-arm-pd", "g1-wbc", "g1-walk", "xcheck", "ik")
