"""Every run's trajectory, kept for replay: the plant's qpos over time and the model it ran on.

A :class:`TrajectoryRecorder` observes the simulator (every step or control period) and writes
``trajectory.npz`` when closed: ``time_s`` (n,), ``qpos`` (n, plant nq, MuJoCo convention, scene
coordinates included), ``q`` (n, robot nq, Pinocchio convention) and the robot's name. Beside it,
``model.xml`` is the plant as it ran (load-time edits included; mesh paths made absolute), so
``mbctl replay RUN_DIR`` needs nothing else. The archive also names the plant (``model_name``, the
MJCF's model name, and ``joints``, its joint names in qpos order), so a replay refuses a
``model.xml`` of another robot even when its nq is the same.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from mbctl.robots.edits import standalone_xml
from mbctl.robots.model_pair import Robot
from mbctl.sim.atomic import write_bytes_atomic, write_text_atomic
from mbctl.sim.exceptions import TrajectoryError
from mbctl.sim.simulator import Simulator

TRAJECTORY_NAME = "trajectory.npz"
MODEL_NAME = "model.xml"
#: Rows of one block of a recorder's samples (the G1's: 1.2 MB), allocated when the last one is full.
BLOCK_ROWS = 4096


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
        self._data = sim.data
        self._qpos_now = sim.data.qpos  # a view into MjData: what a step left, read when kept
        self._kept: list[tuple[np.ndarray, np.ndarray]] = []  # filled blocks (times, rows)
        self._block_t, self._block_q = self._new_block()
        self._i = self._n = 0  # the next row of the current block; the samples kept
        self._keep(float(sim.data.time), self._qpos_now)
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

    @property
    def samples(self) -> int:
        """Samples kept so far (the start included)."""
        return self._n

    def __call__(self, sim: Simulator) -> None:
        """Observer hook: keep the current time and qpos."""
        self._keep(self._data.time, self._qpos_now)

    def _keep(self, t: float, qpos: np.ndarray) -> None:
        """Store one sample: two stores into the current block (a new block when it is full).

        Rows of blocks allocated as they fill, none copied until ``close()``: a new array per step
        (``qpos.copy()``) cost a job's control cycle 5-15 us more (its allocations, spread over the
        heap, evicted the loop's data from the CPU's caches; ``bench/README.md``).
        """
        i = self._i
        if i == BLOCK_ROWS:
            self._kept.append((self._block_t, self._block_q))
            self._block_t, self._block_q = self._new_block()
            i = 0
        self._block_t[i] = t
        self._block_q[i] = qpos
        self._i, self._n = i + 1, self._n + 1

    def _new_block(self) -> tuple[np.ndarray, np.ndarray]:
        return np.empty(BLOCK_ROWS), np.empty((BLOCK_ROWS, self.sim.model.nq))

    def _samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The samples kept: times (n,) [s] and plant qpos (n, nq)."""
        i = self._i
        blocks = [*self._kept, (self._block_t[:i], self._block_q[:i])]
        return np.concatenate([t for t, _ in blocks]), np.concatenate([q for _, q in blocks])

    def _replace_samples(self, t: np.ndarray, qpos: np.ndarray) -> None:
        """Keep these samples (n,), (n, nq) instead of those kept so far."""
        self._kept, self._i, self._n = [(t, qpos)], 0, len(t)

    def close(self) -> Path:
        """Stop and write ``trajectory.npz`` (idempotent)."""
        if not self._closed:
            self._closed = True
            self.sim.remove_observer(self)
            robot = self.sim.robot
            t, qpos = self._samples()
            q = np.array([robot.robot_q(x) for x in qpos]) if len(qpos) else np.zeros((0, robot.nq))
            write_bytes_atomic(self.path, lambda f: np.savez_compressed(
                f, time_s=t, qpos=qpos, q=q, robot=np.array(robot.name),
                model=np.array(MODEL_NAME), track_body=np.array(self.track_body),
                model_name=np.array(model_name(self.sim.model)),
                joints=np.array(joint_names(self.sim.model))))
        return self.path


def base_body(robot: Robot) -> int | None:
    """MuJoCo id of the robot's floating base body, or None for a fixed base."""
    if not robot.has_floating_base:
        return None
    m, first = robot.mj_model, next(iter(robot.joints.values()))
    return int(m.jnt_bodyid[int(np.flatnonzero(m.jnt_qposadr == first.qposadr)[0])])


def model_name(model: mujoco.MjModel) -> str:
    """The MJCF's model name (``<mujoco model="...">``)."""
    return bytes(model.names).split(b"\0", 1)[0].decode()  # the first name is the model's


def joint_names(model: mujoco.MjModel) -> list[str]:
    """The plant's joint names in qpos order (unnamed joints as ``""``)."""
    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in range(model.njnt)]


#: The arrays every trajectory.npz holds.
REQUIRED = ("time_s", "qpos")


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of ``path`` (no pickles); TrajectoryError if it is not a readable npz."""
    import zipfile

    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise TrajectoryError(f"{path} is a single .npy array, not an npz archive of a run")
        with data:
            arrays = {k: np.asarray(data[k]) for k in data.files}
    except TrajectoryError:
        raise
    except (OSError, EOFError, ValueError, zipfile.BadZipFile, KeyError) as exc:
        raise TrajectoryError(f"{path} is damaged (truncated or not an npz archive): "
                              f"{type(exc).__name__}: {exc}") from None
    missing = [k for k in REQUIRED if k not in arrays]
    if missing:
        raise TrajectoryError(f"{path} has no {', '.join(repr(k) for k in missing)} array; it holds "
                              f"{', '.join(sorted(arrays)) or 'nothing'}")
    return arrays


def check_trajectory(arrays: dict[str, np.ndarray], model: mujoco.MjModel, path: Path) -> None:
    """Check a trajectory's arrays against each other and against the plant ``model``.

    Raises:
        TrajectoryError: Zero samples, qpos not (n, model.nq), time_s not (n,), a NaN or inf,
            time going backwards, or a model of another robot than the one recorded (its name or
            its joint names differ).
    """
    t, qpos = arrays["time_s"], arrays["qpos"]
    robot = str(arrays["robot"]) if "robot" in arrays else "?"
    for name, a in (("time_s", t), ("qpos", qpos)):
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
            raise TrajectoryError(f"{path}: {name} holds {a.dtype} values, not real numbers")
    if qpos.size == 0 and t.size == 0:
        raise TrajectoryError(f"{path} holds zero samples: nothing to replay")
    if "model_name" in arrays and str(arrays["model_name"]) != model_name(model):
        raise TrajectoryError(
            f"{path} was recorded on robot {robot!r} (model {str(arrays['model_name'])!r}), but "
            f"{MODEL_NAME} beside it is model {model_name(model)!r}: the run folder mixes two robots")
    if "joints" in arrays:
        recorded, plant = [str(j) for j in np.atleast_1d(arrays["joints"])], joint_names(model)
        if recorded != plant:
            k = next((i for i, (a, b) in enumerate(zip(recorded, plant, strict=False)) if a != b),
                     min(len(recorded), len(plant)))
            ours = recorded[k] if k < len(recorded) else "(none)"
            theirs = plant[k] if k < len(plant) else "(none)"
            raise TrajectoryError(
                f"{path} was recorded on robot {robot!r} with {len(recorded)} joints, but {MODEL_NAME} "
                f"beside it has {len(plant)}; joint {k} is {ours!r} in the recording and {theirs!r} in "
                f"{MODEL_NAME}: the run folder mixes two robots")
    if qpos.ndim != 2 or qpos.shape[1] != model.nq:
        raise TrajectoryError(f"{path}: qpos has shape {qpos.shape}, but the plant in {MODEL_NAME} "
                              f"has nq={model.nq}: expected (samples, {model.nq})")
    if len(qpos) == 0:
        raise TrajectoryError(f"{path}: qpos holds zero samples (time_s {t.size}): nothing to replay")
    if t.shape != (len(qpos),):
        raise TrajectoryError(f"{path}: time_s has shape {t.shape} but qpos has {len(qpos)} rows: "
                              f"expected one time per row, ({len(qpos)},)")
    for name, a in (("time_s", t), ("qpos", qpos)):
        bad = ~np.isfinite(a.reshape(len(a), -1)).all(axis=1)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise TrajectoryError(f"{path}: {name} sample {k} (of {len(a)}) holds NaN or inf "
                                  f"({int(bad.sum())} such samples)")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise TrajectoryError(f"{path}: time_s goes backwards at sample {k}: {t[k]:.6g} s after "
                              f"{t[k - 1]:.6g} s; time must not decrease")


def load_trajectory(folder: Path) -> tuple[mujoco.MjModel, np.ndarray, np.ndarray, int | None]:
    """(plant model, time_s (n,), qpos (n, nq), tracked base body or None) of a run folder.

    Raises:
        FileNotFoundError: The folder has no trajectory (a run from before trajectories).
        ValueError: MuJoCo cannot load the saved model (e.g. its meshes moved).
        TrajectoryError: The trajectory is damaged or does not match the saved model (see
            :func:`check_trajectory`).
    """
    folder = Path(folder)
    path = folder / TRAJECTORY_NAME
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist")
    arrays = _read_npz(path)
    model = mujoco.MjModel.from_xml_path(str(folder / MODEL_NAME))
    check_trajectory(arrays, model, path)
    tb = arrays.get("track_body", np.array(-1))
    track = int(tb) if tb.size == 1 and np.issubdtype(tb.dtype, np.integer) else model.nbody
    if not -1 <= track < model.nbody:
        raise TrajectoryError(f"{path}: track_body {tb.tolist()!r} is not a body id of {MODEL_NAME} "
                              f"(it has {model.nbody} bodies; -1 means none)")
    return model, arrays["time_s"].astype(float), arrays["qpos"].astype(float), \
        (track if track >= 0 else None)
