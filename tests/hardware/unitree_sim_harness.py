"""Unitree's own Python simulator as the robot in the tests: found next to the clone, run headless.

The copy of unitree_mujoco (its ``simulate_python`` and G1 model, read-only, used unchanged; see
its SOURCE.md) lives in ``../shared/unitree_mujoco`` next to the repository, as CI has it (the
same place as the Menagerie copy ``.ci/run`` uses). Without it the tests skip, except in CI,
where they fail: CI must run them (as the G1 model rule in tests/conftest.py).

:func:`unitree_sim` starts tests/hardware/unitree_sim_runner.py as a subprocess on the test's
DDS domain and ``lo``, at a start pose of mbctl's G1 (the same kinematics: Unitree's G1 and
Menagerie's share their joints and feet), and yields it once it serves.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import mbctl
from mbctl.robots.model_pair import Robot

#: Where CI (and a developer's machine) keeps the copy: ``../shared/unitree_mujoco`` next to the clone.
UNITREE_MUJOCO = Path(mbctl.__file__).resolve().parent.parent / "shared" / "unitree_mujoco"
RUNNER = Path(__file__).with_name("unitree_sim_runner.py")
#: Unitree's default SIMULATE_DT [s] (200 Hz), and the G1's own 500 Hz.
UNITREE_DT, G1_DT = 0.005, 0.002
#: The scene the runner loads by default (in unitree_robots/g1): the 29-DoF G1 on a flat floor. Their
#: simulator's default ``scene.xml`` is the same G1 with terrain: a 0.2 m box step from 1.0 m ahead of
#: the origin (a cylinder on it), stairs, rough ground; a forward walk ran into the step (its toes at
#: 3.3 s, the pelvis 0.69 m on) and turned and fell.
FLAT_SCENE = "scene_29dof.xml"
#: The watchdog [periods] of the lock-step runs (this simulator's, ``mbctl serve g1 --lockstep``'s):
#: they share 2 cores with other work (CI's second pytest worker, its bridges and clients), where a
#: stall of either process is not a lost link (lock-step: the simulator waits for the client); 100
#: periods of 2 ms once fired in CI mid-walk. The watchdog itself is tested against a fake robot
#: (tests/hardware/test_unitree_g1.py) and its timing by bench/bench_dds.py.
LOCKSTEP_WATCHDOG_PERIODS = 500
#: Seconds the runner gets to load MuJoCo and join DDS.
START_S = 120.0


def unitree_mujoco() -> Path:
    """The copy's root; skips the test without it (fails it in CI)."""
    bridge = UNITREE_MUJOCO / "simulate_python" / "unitree_sdk2py_bridge.py"
    if bridge.is_file():
        return UNITREE_MUJOCO
    message = f"Unitree's simulator (unitree_mujoco) not at {UNITREE_MUJOCO}"
    if os.environ.get("CI"):
        pytest.fail(f"CI must have {message} (../shared/unitree_mujoco next to the clone)")
    pytest.skip(message)


def start_pose(robot: Robot, q: np.ndarray) -> dict:
    """mbctl's configuration ``q`` (nq,) as the runner's start (base x, y, z, qw, qx, qy, qz; joints)."""
    base = [*q[:3], q[6], q[3], q[4], q[5]]  # MuJoCo's quaternion order w, x, y, z
    joints = {name: float(q[j.idx_q]) for name, j in robot.joints.items() if j.kind in ("hinge", "slide")}
    return {"base": [float(x) for x in base], "joints": joints}


@dataclass
class UnitreeSim:
    """A running simulator: its process, and once it ended what it wrote (its last line: the pelvis).

    Attributes:
        proc: The runner's process.
        log: Its stderr after the serving line (set when it has stopped).
    """

    proc: subprocess.Popen[str]
    log: str = ""

    def pelvis_z_m(self) -> dict[str, float]:
        """The pelvis height [m] it reported at its end: start, min while commanded (before the damping
        command), final."""
        found = re.search(r"pelvis z start (\S+) m, min (\S+) m until the damping command, final (\S+) m",
                          self.log)
        if found is None:
            pytest.fail(f"Unitree's simulator did not report the pelvis: {self.log}")
        return dict(zip(("start", "min", "final"), map(float, found.groups()), strict=True))


@contextmanager
def unitree_sim(domain: int, robot: Robot, q: np.ndarray, folder: Path, *, dt: float = UNITREE_DT,
                pace: str = "command", idle_timeout_s: float = 30.0,
                truth: Path | None = None, scene: str = FLAT_SCENE) -> Iterator[UnitreeSim]:
    """Unitree's simulator on ``domain`` (lo) with the G1 at ``q``; yields it once it serves.

    At the end of the block it is stopped (SIGINT) unless it stopped by itself; wait for that (its
    idle timeout) with ``sim.proc.wait()`` inside the block to read its own last line.

    Args:
        domain: The test's DDS domain.
        robot: mbctl's G1 (its joint names and configuration layout).
        q: The start configuration (nq,), Pinocchio convention.
        folder: Where the start pose file is written.
        dt: SIMULATE_DT [s].
        pace: "command" (one physics step per command, no faster than real time) or "wall".
        idle_timeout_s: It stops this long [s] after its last command (or its start).
        truth: Where it writes the true CoM and pelvis per step when it stops (CSV), if given.
        scene: The scene file in unitree_robots/g1 (``scene.xml``: their default, with terrain).
    """
    root = unitree_mujoco()
    start = folder / "unitree_start.json"
    start.write_text(json.dumps(start_pose(robot, q)))
    args = ["--root", str(root), "--domain", str(domain), "--dt", str(dt), "--pace", pace,
            "--start", str(start), "--idle-timeout", str(idle_timeout_s), "--scene", scene,
            *(["--truth", str(truth)] if truth else [])]
    proc = subprocess.Popen([sys.executable, str(RUNNER), *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    sim = UnitreeSim(proc)
    try:
        line = _first_line(proc)
        if "serving" not in line:
            pytest.fail(f"Unitree's simulator did not start: {line}{proc.stderr.read()}")
        yield sim
    finally:
        sim.log = stop(proc)


def _first_line(proc: subprocess.Popen[str]) -> str:
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(proc.stderr.readline()), daemon=True)
    reader.start()
    reader.join(START_S)
    if not got:
        proc.kill()
        pytest.fail(f"Unitree's simulator wrote nothing within {START_S:g} s (killed)")
    return got[0]


def stop(proc: subprocess.Popen[str]) -> str:
    """End a process of the tests' (a simulator, a bridge): Ctrl-C, then kill; the rest of its stderr."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    rest = proc.stderr.read() if proc.stderr and not proc.stderr.closed else ""
    for pipe in (proc.stdout, proc.stderr):
        if pipe:
            pipe.close()
    return rest


def kill_after(proc: subprocess.Popen[str], delay_s: float) -> threading.Timer:
    """SIGKILL ``proc`` after ``delay_s`` [s] (a robot whose link dies mid-run); the timer, started."""
    timer = threading.Timer(delay_s, lambda: proc.poll() is None and proc.kill())
    timer.daemon = True
    timer.start()
    time.sleep(0)
    return timer


def true_com_rms_m(truth: Path, run_csv: Path) -> float:
    """The RMS [m] of the plant's CoM against a g1-wbc run's CoM reference, from the runner's truth.

    In lock-step cycle k uses the state of the runner's row k + 1 (its first step follows the
    first command, whose state is the held start). The leg-kinematics estimator cannot observe
    x, y, so they are compared as displacements from the first cycle; z is absolute.

    Args:
        truth: The runner's ``--truth`` CSV.
        run_csv: The run's ``g1_wbc.csv``.
    """
    rows = np.genfromtxt(truth, delimiter=",", names=True)
    log = np.genfromtxt(run_csv, delimiter=",", names=True)
    axes = ("x", "y", "z")
    ref = np.column_stack([log[f"com_ref_{a}_m"] for a in axes])
    estimated = np.column_stack([log[f"com_{a}_m"] for a in axes])
    com = np.column_stack([rows[f"com_{a}_m"] for a in axes])[1:len(log) + 1]
    com[:, :2] += estimated[0, :2] - com[0, :2]
    return float(np.sqrt(((com - ref) ** 2).sum(axis=1).mean()))


def walk_truth(truth: Path, cycles: int) -> dict[str, float]:
    """What a run of ``cycles`` lock-step cycles did, from the runner's truth (rows 1..cycles).

    Returns:
        ``dx_m``, ``dy_m``: the pelvis's travel in the world frame [m]; ``max_yaw_rad``: its
        largest heading [rad] (absolute); ``min_z_m``: its lowest height [m];
        ``terrain_contacts``: steps with the robot touching the scene's terrain.
    """
    rows = np.genfromtxt(truth, delimiter=",", names=True)[1:cycles + 1]
    return {"dx_m": float(rows["base_x_m"][-1] - rows["base_x_m"][0]),
            "dy_m": float(rows["base_y_m"][-1] - rows["base_y_m"][0]),
            "max_yaw_rad": float(np.abs(rows["base_yaw_rad"]).max()),
            "min_z_m": float(rows["base_z_m"].min()),
            "terrain_contacts": int((rows["terrain_contacts"] > 0).sum())}
