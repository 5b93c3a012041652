"""External pushes on the plant: a force on a body held for a duration (``MjData.xfrc_applied``)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from mbctl.sim.exceptions import SimError


@dataclass(frozen=True)
class Push:
    """A force ``force_W`` (3,) [N] in W at a body's centre of mass from ``start_s`` for ``duration_s``."""

    body: str
    force_W: tuple[float, float, float]
    start_s: float
    duration_s: float

    @property
    def impulse_n_s(self) -> float:
        """The impulse ``|F| T`` [N s]."""
        return float(np.linalg.norm(self.force_W)) * self.duration_s


class PushSchedule:
    """Applies pushes as simulated time passes: ``apply(data)`` before each step.

    A :class:`~mbctl.sim.simulator.Perturbation`: ``sim.add_perturbation(schedule)`` applies it
    before every physics step.

    Attributes:
        pushes: The pushes.
        force_W: Total force (3,) [N] applied at the last step.

    Raises:
        SimError: An unknown body, a non-finite force or a non-positive duration.
    """

    def __init__(self, model: mujoco.MjModel, pushes: list[Push]):
        self._pushes = []
        for p in pushes:
            bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, p.body)
            if bid < 0:
                raise SimError(f"push on unknown body {p.body!r}")
            f: npt.NDArray[np.float64] = np.asarray(p.force_W, dtype=float)
            if f.shape != (3,) or not np.all(np.isfinite(f)) or not p.duration_s > 0:
                raise SimError(f"push {p!r}: force must be finite (3,) [N] and duration > 0 s")
            self._pushes.append((bid, f, p.start_s, p.start_s + p.duration_s))
        self.pushes = list(pushes)
        self.force_W = np.zeros(3)

    def apply(self, data: mujoco.MjData) -> np.ndarray:
        """Set ``xfrc_applied`` for the current time; returns the total applied force (3,) [N]."""
        t = data.time
        total = np.zeros(3)
        for bid, *_ in self._pushes:
            data.xfrc_applied[bid, :3] = 0.0
        for bid, f, t0, t1 in self._pushes:
            if t0 <= t < t1:
                data.xfrc_applied[bid, :3] += f
                total += f
        self.force_W = total
        return total
