"""The names ``mbctl g1-walk`` lists in its help, free of heavy imports (as :mod:`mbctl.jobs.choices`)."""

from __future__ import annotations

#: ``mbctl g1-walk SCENARIO``.
WALK_SCENARIOS = ("forward", "backward", "side", "turn", "course", "push")

#: ``--push-phase``: where in the gait a push starts (``mbctl.jobs.g1_walk_push.PUSH_PHASES``).
WALK_PUSH_PHASES = ("early", "late", "double")

#: ``--gait``: the walking options (quick, the default: ``quick_gait()``, up to ~1 m/s; normal:
#: ``WalkingConfig()``'s).
WALK_GAITS = ("quick", "normal")

#: Each scenario's default command: (vx [m/s], vy [m/s], yaw rate [rad/s]).
WALK_DEFAULT_SPEED = {"forward": (0.3, 0.0, 0.0), "backward": (0.3, 0.0, 0.0), "side": (0.0, 0.2, 0.0),
                      "turn": (0.0, 0.0, 0.5), "course": (0.3, 0.15, 0.3), "push": (0.3, 0.0, 0.0)}

#: Default simulated time [s] per scenario.
WALK_DEFAULT_DURATION_S = {"forward": 20.0, "backward": 20.0, "side": 20.0, "turn": 20.0, "course": 60.0,
                           "push": 28.0}
