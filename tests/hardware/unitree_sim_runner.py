"""Unitree's Python simulator, headless: its ``UnitreeSdk2Bridge`` unchanged, MuJoCo stepped here.

Run by tests/hardware/unitree_sim_harness.py as a subprocess (one DDS participant per process, as
Unitree's own script). It does what ``simulate_python/unitree_mujoco.py`` does, without the
viewer that script opens at import:

1. ``config`` and ``pygame`` are stand-in modules in ``sys.modules``: the G1 scene (``--scene``:
   ``scene.xml`` by default as theirs, with its terrain; the harness gives the flat one), the test's
   domain, ``lo``, ``SIMULATE_DT``, no joystick (``unitree_sdk2py_bridge`` imports pygame for the
   joystick only);
2. the scene is loaded and ``opt.timestep`` set to ``SIMULATE_DT`` (as their script does), the
   robot put at the start pose given (joint angles by name, base pose);
3. ``ChannelFactoryInitialize(DOMAIN_ID, INTERFACE)`` (Unitree's SDK configuration of ``lo``) and
   their bridge class, whose own threads publish LowState every ``SIMULATE_DT`` and whose handler
   turns each LowCmd into ``ctrl`` (``tau + kp (q* - q) + kd (dq* - dq)`` at the command's arrival);
4. the robot is held still (no physics) until the first command, as a harness holds a robot;
5. then MuJoCo steps, either paced to wall-clock time at ``SIMULATE_DT`` as their simulation thread
   (``--pace wall``), or in lock-step (``--pace command``): one step once a command has come since
   the step before, no faster than real time, followed by their ``PublishLowState``, so a loaded
   machine slows the run instead of changing it (their publishing thread is stopped once the first
   command came). Each step uses the command answering the state before it: stepping once per
   command *counted* instead let a step run on the previous command whenever the answer to the
   state just published came late (under load), so the explicit motor law acted on a 2-step-old
   state and the G1 fell at 2 ms. Commands that came together (a state answered twice) are
   counted and said at the end.

It stops after ``--idle-timeout`` seconds without a command (counted from its start), after
``--duration``, or when the physics diverges (non-finite state, MuJoCo's divergence warnings):
exit 1 with the reason. The subclass below adds only a lock (their handler runs on the DDS
thread) and a command count; it calls their methods for everything else.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
import types
from pathlib import Path

#: The first line on stderr once the bridge serves (the harness waits for it).
SERVING = "unitree simulator serving"


def stand_in_modules(root: Path, domain: int, dt: float, scene: str = "scene.xml") -> None:
    """Put the ``config`` and ``pygame`` stand-ins in ``sys.modules`` and their code on ``sys.path``."""
    config = types.ModuleType("config")
    config.ROBOT = "g1"
    config.ROBOT_SCENE = str(root / "unitree_robots" / "g1" / scene)
    config.DOMAIN_ID = domain
    config.INTERFACE = "lo"
    config.USE_JOYSTICK = 0
    config.JOYSTICK_TYPE = "xbox"
    config.JOYSTICK_DEVICE = 0
    config.PRINT_SCENE_INFORMATION = False
    config.ENABLE_ELASTIC_BAND = False
    config.SIMULATE_DT = dt
    config.VIEWER_DT = 0.02
    sys.modules["config"] = config
    sys.modules["pygame"] = types.ModuleType("pygame")  # the joystick's; never used without one
    sys.path.insert(0, str(root / "simulate_python"))


def set_start(mj_model, mj_data, start: dict) -> None:
    """The base pose (x, y, z, qw, qx, qy, qz) and the joint angles by name, then the sensors."""
    import mujoco

    free = next(j for j in range(mj_model.njnt) if mj_model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE)
    adr = mj_model.jnt_qposadr[free]
    mj_data.qpos[adr:adr + 7] = start["base"]
    for name, value in start["joints"].items():
        mj_data.qpos[mj_model.joint(name).qposadr[0]] = value
    mujoco.mj_forward(mj_model, mj_data)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, required=True, help="the unitree_mujoco copy")
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--dt", type=float, default=0.005, help="SIMULATE_DT [s] (their default 0.005)")
    parser.add_argument("--pace", choices=("wall", "command"), default="command")
    parser.add_argument("--start", type=Path, required=True, help="JSON: base pose and joint angles")
    parser.add_argument("--idle-timeout", type=float, default=30.0)
    parser.add_argument("--duration", type=float, default=300.0)
    parser.add_argument("--scene", default="scene.xml", help="the G1's scene file in unitree_robots/g1")
    parser.add_argument("--truth", type=Path, help="CSV: step, time and the true CoM and pelvis per step")
    args = parser.parse_args()
    # Ctrl-C (the harness's stop) sets a flag the loop reads: a KeyboardInterrupt raised inside the
    # condition's wait left its lock released under the ``with`` (CI: "release unlocked lock", no report)
    interrupted = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: interrupted.set())
    stand_in_modules(args.root, args.domain, args.dt, args.scene)
    import config
    import mujoco
    from unitree_sdk2py.core.channel import ChannelFactoryInitialize
    from unitree_sdk2py_bridge import UnitreeSdk2Bridge

    class HeldBridge(UnitreeSdk2Bridge):
        """Their bridge with a lock around their handler and publisher, and a count of commands."""

        def __init__(self, mj_model, mj_data):
            self.lock = threading.Lock()
            self.commands = 0
            self.damping = False
            self.arrived = threading.Condition(self.lock)
            super().__init__(mj_model, mj_data)

        def LowCmdHandler(self, msg):  # noqa: N802 - their name
            with self.lock:
                super().LowCmdHandler(msg)
                self.commands += 1
                # the damping command (no stiffness, no torque): the client's loop has ended
                self.damping = all(m.kp == 0 and m.tau == 0 for m in msg.motor_cmd[: self.num_motor])
                self.arrived.notify()

        def PublishLowState(self):  # noqa: N802 - their name
            with self.lock:
                super().PublishLowState()

    mj_model = mujoco.MjModel.from_xml_path(config.ROBOT_SCENE)
    mj_data = mujoco.MjData(mj_model)
    mj_model.opt.timestep = config.SIMULATE_DT
    set_start(mj_model, mj_data, json.loads(args.start.read_text()))
    ChannelFactoryInitialize(config.DOMAIN_ID, config.INTERFACE)
    bridge = HeldBridge(mj_model, mj_data)
    print(f"{SERVING} on DDS domain {config.DOMAIN_ID} ({config.INTERFACE}), SIMULATE_DT "
          f"{config.SIMULATE_DT} s, pace {args.pace}", file=sys.stderr, flush=True)
    physics = Physics(bridge, mj_model, mj_data, args.pace, interrupted)
    why = physics.run(args.idle_timeout, args.duration)
    if args.truth is not None:
        import numpy as np

        np.savetxt(args.truth, np.asarray(physics.truth), delimiter=",", comments="",
                   header="step,time_s,com_x_m,com_y_m,com_z_m,base_x_m,base_y_m,base_z_m,base_yaw_rad,"
                          "terrain_contacts")
    base_z = physics.base_z
    print(f"stopped after {physics.steps} steps ({why}; {physics.merged} commands merged); pelvis z "
          f"start {base_z[0]:.4f} m, min {min(base_z):.4f} m until the damping command, final "
          f"{mj_data.qpos[2]:.4f} m",
          file=sys.stderr, flush=True)
    return 1 if why == "diverged" else 0


class Physics:
    """MuJoCo stepped for Unitree's bridge: held until its first command, then paced (see the docstring).

    Args:
        bridge: Their bridge (with the lock and count of ``HeldBridge``).
        mj_model: The scene's model (``opt.timestep`` = SIMULATE_DT).
        mj_data: Its data, at the start pose.
        pace: "wall" or "command".
        interrupted: Set on Ctrl-C; the loop then stops ("interrupted").
    """

    def __init__(self, bridge, mj_model, mj_data, pace: str, interrupted: threading.Event):
        import mujoco

        self.bridge, self.model, self.data, self.pace = bridge, mj_model, mj_data, pace
        self.steps = 0
        self.interrupted = interrupted
        self.merged = 0  # commands that came with another after the first step (command pace)
        #: per step: step, time [s], the CoM and the pelvis [m] and the pelvis's yaw [rad] of the state
        #: its LowState carries (MuJoCo computes them before it integrates, as the sensors), and the
        #: robot's contacts with the scene's geoms other than its floor (scene.xml's step, stairs)
        self.truth: list[tuple[float, ...]] = []
        self.pelvis = mj_model.body("pelvis").id
        floor = mj_model.geom("floor").id
        self.terrain = {g for g in range(mj_model.ngeom) if mj_model.geom_bodyid[g] == 0 and g != floor}
        self.base_z = [float(mj_data.qpos[2])]  # the pelvis height [m] at the start and while commanded
        warning = mujoco.mjtWarning
        self._divergence = [int(w) for w in (warning.mjWARN_BADQPOS, warning.mjWARN_BADQVEL,
                                             warning.mjWARN_BADQACC)]

    def run(self, idle_timeout_s: float, duration_s: float) -> str:
        """Until idle (no command for ``idle_timeout_s`` since the last or the start), the duration, or
        a divergence; why it stopped."""
        bridge, dt = self.bridge, self.model.opt.timestep
        t0 = time.monotonic()
        last_command, seen = t0, 0
        while True:  # held until the first command; then the physics runs
            if self.interrupted.is_set():
                return "interrupted"
            with bridge.lock:
                if self.pace == "command" and bridge.commands == seen:
                    bridge.arrived.wait(timeout=dt)
                new = bridge.commands - seen
                seen = bridge.commands
            now = time.monotonic()
            if new:
                last_command = now
            if now - t0 > duration_s:
                return "duration"
            if now - last_command > idle_timeout_s:
                return "idle"
            if not seen:
                if self.pace == "wall":
                    time.sleep(dt)
                continue
            if self.pace == "command" and self.steps == 0:
                bridge.lowStateThread.Wait(1.0)  # from now on one state per command, published below
            if self.pace == "command":
                if not new:  # lock-step: no step without a command answering the last state
                    continue
                if self.steps:  # (before the first step their thread published too)
                    self.merged += new - 1
            if not self.step():
                return "diverged"

    def step(self) -> bool:
        """One physics step (then, in command pace, their LowState), no faster than real time; if sane."""
        import mujoco
        import numpy as np

        start, d = time.perf_counter(), self.data
        with self.bridge.lock:
            mujoco.mj_step(self.model, d)
        self.steps += 1
        if not self.bridge.damping:
            self.base_z.append(float(d.qpos[2]))
        w, x, y, z = d.xquat[self.pelvis]
        terrain = sum(c.geom1 in self.terrain or c.geom2 in self.terrain for c in d.contact[:d.ncon])
        self.truth.append((self.steps, d.time, *d.subtree_com[self.pelvis], *d.xpos[self.pelvis],
                           np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)), terrain))
        warned = any(d.warning[w].number for w in self._divergence)
        if warned or not (np.isfinite(d.qpos).all() and np.isfinite(d.qacc).all()):
            print(f"diverged at t={d.time:.3f} s (step {self.steps})", file=sys.stderr, flush=True)
            return False
        if self.pace == "command":
            self.bridge.PublishLowState()
        wait = self.model.opt.timestep - (time.perf_counter() - start)
        if wait > 0:
            time.sleep(wait)
        return True

if __name__ == "__main__":
    sys.exit(main())
