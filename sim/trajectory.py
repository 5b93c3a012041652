"""Every run's trajectory, kept for replay: the plant's qpos over time and the model it ran on.

A :class:`TrajectoryRecorder` observes the simulator (every step or control period) and writes
``trajectory.npz`` when closed: ``time_s`` (n,), ``qpos`` (n, plant nq, MuJoCo convention, scene
coordinates included), ``q`` (n, robot nq, Pinocchio convention) and the robot's name. Beside it,
``model.xml`` is the plant as it ran (load-time edits included; mesh paths made absolute), so
``mbctl replay RUN_DIR`` needs nothing else.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from mbctl.robots.edits import standalone_xml
from mbctl.robots.model_pair import Robot
from mbctl.sim.atomic import write_bytes_atomic, write_text_atomic
from mbctl.sim.simulator import Simulator

TRAJECTORY_NAME = "trajectory.npz"
MODEL_NAME = "model.xml"


def plant_xml(robot: Robot) -> str:
    """The plant's MJCF (with its load-time edits), asset paths absolute so it loads from anywhere."""
    return standalone_xml(robot)


class TrajectoryRecorder:
    """Records the plant's qpos after every step/sync; ``close()`` writes the sidecar files."""

    def __init__(self, sim: Simulator, folder: Path):
        self.sim, self.folder = sim, Path(folder)
        self.model_path = self.folder / MODEL_NAME
        self.path = self.folder / TRAJECTORY_NAME
        write_text_atomic(self.model_path, plant_xml(sim.robot))
        self._t: list[float] = [float(sim.data.time)]
        self._qpos: list[np.ndarray] = [sim.data.qpos.copy()]
        self._closed = False
        #: MuJoCo id of the floating base a camera follows in replays (-1: fixed base).
        self.track_body = -1
        base = base_body(sim.robot)
        if base is not None:
            self.track_body = base

    def attach(self) -> TrajectoryRecorder:
        """Start recording: register as the simulator's observer."""
        self.sim.add_observer(self)
        return self

    def __call__(self, sim: Simulator) -> None:
        """Observer hook: keep the current time and qpos."""
        self._t.append(float(sim.data.time))
        self._qpos.append(sim.data.qpos.copy())

    def close(self) -> Path:
        """Stop and write ``trajectory.npz`` (idempotent)."""
        if not self._closed:
            self._closed = True
            self.sim.remove_observer(self)
            robot = self.sim.robot
            qpos = np.array(self._qpos)
            q = np.array([robot.robot_q(x) for x in qpos]) if len(qpos) else np.zeros((0, robot.nq))
            write_bytes_atomic(self.path, lambda f: np.savez_compressed(
                f, time_s=np.array(self._t), qpos=qpos, q=q, robot=np.array(robot.name),
                model=np.array(MODEL_NAME), track_body=np.array(self.track_body)))
        return self.path


def base_body(robot: Robot) -> int | None:
    """MuJoCo id of the robot's floating base body, or None for a fixed base."""
    if not robot.has_floating_base:
        return None
    m, first = robot.mj_model, next(iter(robot.joints.values()))
    return int(m.jnt_bodyid[int(np.flatnonzero(m.jnt_qposadr == first.qposadr)[0])])


def load_trajectory(folder: Path) -> tuple[mujoco.MjModel, np.ndarray, np.ndarray, int | None]:
    """(plant model, time_s (n,), qpos (n, nq), tracked base body or None) of a run folder.

    Raises:
        FileNotFoundError: The folder has no trajectory (a run from before trajectories).
        ValueError: MuJoCo cannot load the saved model (e.g. its meshes moved).
    """
    folder = Path(folder)
    with np.load(folder / TRAJECTORY_NAME) as data:
        t, qpos = np.array(data["time_s"]), np.array(data["qpos"])
        track = int(data["track_body"]) if "track_body" in data else -1
    model = mujoco.MjModel.from_xml_path(str(folder / MODEL_NAME))
    return model, t, qpos, (track if track >= 0 else None)
