"""Errors raised by the MuJoCo backend."""

from __future__ import annotations

from mbctl.exceptions import ToolkitError


class SimError(ToolkitError):
    """Base class of simulator errors."""


class OutputPathError(SimError):
    """An output file cannot be created safely at its path.

    A symbolic link sits there (outputs never follow one), or a directory or another non-regular
    file, or the OS refuses to create it.
    """


class SimulationDiverged(SimError):
    """MuJoCo flagged a diverging state (bad qpos, qvel or qacc) and reset its data.

    Attributes:
        warnings: The divergence warnings that fired, by MuJoCo name, with their counts.
        time_s: Simulated time [s] at which the steps that diverged began (MuJoCo's reset restarts
            its own clock, so it is taken before them).
    """

    def __init__(self, warnings: dict[str, int], time_s: float, hint: str = ""):
        self.warnings = warnings
        self.time_s = time_s
        names = ", ".join(f"{k} (x{v})" for k, v in warnings.items())
        super().__init__(
            f"Simulation diverged near t={time_s:.4f} s: MuJoCo raised {names} and reset its state. "
            "Reduce the timestep, the gains or the commanded torques." + (f" {hint}" if hint else "")
        )


class TrajectoryError(SimError):
    """A recorded trajectory (``trajectory.npz`` + ``model.xml``) that is damaged or inconsistent."""
