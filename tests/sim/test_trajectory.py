"""Replay input: a damaged trajectory.npz or a model.xml of another robot is refused, naming the problem."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from mbctl.robots import load_robot, torque
from mbctl.sim import Simulator
from mbctl.sim.exceptions import TrajectoryError
from mbctl.sim.trajectory import MODEL_NAME, TRAJECTORY_NAME, TrajectoryRecorder, load_trajectory

ONE_DOF_ARM = """<mujoco model="pendulum_pair">
  <worldbody>
    <body name="a"><joint name="swing" axis="0 0 1"/><geom size="0.05" mass="1"/>
      <body name="b" pos="0.2 0 0"><joint name="tilt" axis="0 1 0"/><geom size="0.05" mass="1"/></body>
    </body>
  </worldbody>
</mujoco>
"""


def _record(robot_name: str, folder: Path) -> Path:
    sim = Simulator(load_robot(robot_name))
    rec = TrajectoryRecorder(sim, folder).attach()
    for _ in range(20):
        sim.step(torque([1.0, -0.5]))
    rec.close()
    return folder


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    return _record("two_link_torque", tmp_path_factory.mktemp("traj") / "run")


def _damaged(run_dir: Path, tmp_path: Path, **change) -> Path:
    """A copy of the run with the archive's arrays changed (None drops one)."""
    folder = tmp_path / "damaged"
    shutil.copytree(run_dir, folder)
    with np.load(folder / TRAJECTORY_NAME) as data:
        arrays = {k: data[k] for k in data.files}
    for key, value in change.items():
        if value is None:
            arrays.pop(key)
        else:
            arrays[key] = value(arrays) if callable(value) else value
    np.savez_compressed(folder / TRAJECTORY_NAME, **arrays)
    return folder


def test_an_intact_run_loads(run_dir):
    model, t, qpos, track = load_trajectory(run_dir)
    assert qpos.shape == (21, model.nq) == (21, 2) and t[-1] == pytest.approx(0.04) and track is None


@pytest.mark.parametrize(("change", "message"), [
    ({"qpos": lambda a: a["qpos"][:, :1]}, r"qpos has shape \(21, 1\), but the plant in model.xml has nq=2"),
    ({"qpos": lambda a: np.where(np.arange(21)[:, None] == 7, np.nan, a["qpos"])},
     "qpos sample 7 \\(of 21\\) holds NaN or inf"),
    ({"time_s": lambda a: a["time_s"][::-1].copy()}, "time_s goes backwards at sample 1"),
    ({"time_s": lambda a: a["time_s"][:10]}, r"time_s has shape \(10,\) but qpos has 21 rows"),
    ({"time_s": lambda a: np.zeros(0), "qpos": lambda a: np.zeros((0, 2))}, "holds zero samples"),
    ({"qpos": None}, "has no 'qpos' array; it holds"),
    ({"qpos": lambda a: a["qpos"].astype(str)}, "qpos holds <U32 values, not real numbers"),
    ({"track_body": np.array(99)}, "track_body 99 is not a body id of model.xml"),
])
def test_a_damaged_archive_is_refused_naming_the_problem(run_dir, tmp_path, change, message):
    with pytest.raises(TrajectoryError, match=message):
        load_trajectory(_damaged(run_dir, tmp_path, **change))


def test_a_truncated_or_foreign_file_is_refused(run_dir, tmp_path):
    folder = tmp_path / "cut"
    shutil.copytree(run_dir, folder)
    data = (folder / TRAJECTORY_NAME).read_bytes()
    (folder / TRAJECTORY_NAME).write_bytes(data[: len(data) // 2])
    with pytest.raises(TrajectoryError, match="is damaged \\(truncated or not an npz archive\\)"):
        load_trajectory(folder)
    (folder / TRAJECTORY_NAME).write_text("not an archive")
    with pytest.raises(TrajectoryError, match="is damaged"):
        load_trajectory(folder)
    np.save(folder / "one.npy", np.zeros(3))
    shutil.move(folder / "one.npy", folder / TRAJECTORY_NAME)
    with pytest.raises(TrajectoryError, match="single .npy array"):
        load_trajectory(folder)


def test_a_model_of_another_robot_with_the_same_nq_is_refused(run_dir, tmp_path):
    folder = tmp_path / "mixed"
    shutil.copytree(run_dir, folder)
    (folder / MODEL_NAME).write_text(ONE_DOF_ARM)  # nq = 2, as the arm's
    with pytest.raises(TrajectoryError, match="recorded on robot 'two_link_torque' \\(model "
                                              "'two_link_torque'\\), but model.xml beside it is model "
                                              "'pendulum_pair'"):
        load_trajectory(folder)
    # the same model name, other joints: still refused, naming the first joint that differs
    (folder / MODEL_NAME).write_text(ONE_DOF_ARM.replace("pendulum_pair", "two_link_torque"))
    with pytest.raises(TrajectoryError, match="joint 0 is 'shoulder' in the recording and 'swing'"):
        load_trajectory(folder)
