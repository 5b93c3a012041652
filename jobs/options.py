"""Each job's parameters from its command-line options, named as the options are.

One function per job takes the CLI's option values (the option name with dashes as
underscores: ``--model-error`` is ``model_error``, in the CLI's units) and returns the job's
frozen parameter dataclass. The CLI commands call these functions, and ``mbctl sweep`` reads
their signatures (names, types, defaults) to parse ``--param NAME=V1,V2``, so the command line and
the sweep cannot disagree on a name, a unit or a default. ``tests/cli`` checks that every
command's signature matches its function here.

Only parsing and unit conversion live here; validation stays in the dataclasses.
"""

from __future__ import annotations

import math
from pathlib import Path

from mbctl.control.exceptions import IKSetupError
from mbctl.jobs.demo import DemoConfig
from mbctl.jobs.excite import ExciteParams
from mbctl.jobs.g1 import ArmPDParams, StandParams, TrackParams
from mbctl.jobs.g1_wbc import WBCParams
from mbctl.jobs.identify import IdentifyParams
from mbctl.jobs.ik import IKParams
from mbctl.jobs.joint_step import JointStepParams
from mbctl.jobs.plant_options import PlantOptions
from mbctl.jobs.workspace import WorkspaceParams
from mbctl.jobs.xcheck import XcheckParams


def demo(controller: str = "ct", compare: bool = False, model_error: float = 0.0,
         duration: float | None = None, side: float = 0.2, speed: float = 0.5, omega: float = 30.0,
         gravity: bool = True, max_rms_mm: float | None = None, payload: str | None = None,
         plant_error: float = 0.0, controller_model: str | None = None) -> DemoConfig:
    """``mbctl demo``: model_error in %, duration in s, side in m, speed in m/s, omega in rad/s, mm.

    The plant options: payload KG@BODY[:X,Y,Z], plant_error in %, controller_model an MJCF file.
    """
    return DemoConfig(controller=controller, side_m=side, max_speed_m_s=speed, omega_rad_s=omega,
                      duration_s=duration, model_error_pct=model_error, gravity=gravity, compare=compare,
                      max_rms_error_m=None if max_rms_mm is None else max_rms_mm * 1e-3,
                      plant=PlantOptions(payload, plant_error, controller_model))


def g1_stand(duration: float = 10.0, omega: float = 10.0, zeta: float = 1.0,
             model_dir: str | None = None, payload: str | None = None, plant_error: float = 0.0,
             controller_model: str | None = None) -> StandParams:
    """``mbctl g1-stand``: duration in s, omega in rad/s, zeta (-); plant options."""
    return StandParams(duration, omega, zeta, model_dir, PlantOptions(payload, plant_error, controller_model))


def g1_track(duration: float | None = None, omega: float = 40.0, zeta: float = 1.0,
             max_rms_rad: float | None = None, model_dir: str | None = None, payload: str | None = None,
             plant_error: float = 0.0, controller_model: str | None = None) -> TrackParams:
    """``mbctl g1-track``: duration in s, omega in rad/s, zeta (-), max_rms_rad in rad; plant options."""
    return TrackParams(duration, omega, zeta, max_rms_rad, model_dir,
                       PlantOptions(payload, plant_error, controller_model))


def g1_arm_pd(duration: float | None = None, side: str = "left", gravity_feedforward: bool = True,
              max_rms_rad: float | None = None, model_dir: str | None = None, payload: str | None = None,
              plant_error: float = 0.0, controller_model: str | None = None) -> ArmPDParams:
    """``mbctl g1-arm-pd``: duration in s, side left or right, max_rms_rad in rad; plant options."""
    return ArmPDParams(duration, side, gravity_feedforward, max_rms_rad, model_dir,
                       PlantOptions(payload, plant_error, controller_model))


def g1_wbc(scenario: str = "stand", duration: float | None = None, impulse: float = 10.0,
           direction: float | None = None, model_error: float = 0.0,
           model_dir: str | None = None) -> WBCParams:
    """``mbctl g1-wbc``: duration in s, impulse in N s, direction in deg, model_error in %."""
    return WBCParams(scenario, duration, impulse, direction, model_error, model_dir)


def joint_step(robot: str, joint: str, delta: float, steps: int = 250, keyframe: str | None = None,
               sensor: list[str] | None = None, scene: str | None = None,
               model_dir: str | None = None, payload: str | None = None, plant_error: float = 0.0,
               controller_model: str | None = None) -> JointStepParams:
    """``mbctl joint-step``: delta in rad (m for a slide joint), steps of the physics; plant options."""
    return JointStepParams(robot, joint, delta, steps, keyframe, tuple(sensor or ()), scene, model_dir,
                           PlantOptions(payload, plant_error, controller_model))


def xcheck(robot: str, scene: str | None = None, states: int = 100, seed: int = 0,
           json_path: Path | None = None, pin_model: Path | None = None, gravity: bool = False,
           model_dir: str | None = None, analytic: str = "mujoco",
           root: list[str] | None = None) -> XcheckParams:
    """``mbctl xcheck``: states random states drawn from seed; root bodies select the robot's trees."""
    return XcheckParams(robot, scene, states, seed, json_path, pin_model, gravity, model_dir, analytic,
                        tuple(root or ()))


def workspace(robot: str = "two_link", samples: int = 121) -> WorkspaceParams:
    """``mbctl workspace``: samples per joint."""
    return WorkspaceParams(robot, samples)


def parse_vector(text: str, n: int, what: str) -> tuple[float, ...]:
    """``"X,Y,Z"`` -> floats; IKSetupError naming ``what`` and the expected form otherwise."""
    parts = [p.strip() for p in text.split(",")]
    form = ",".join("XYZ"[:n]) if n <= 3 else f"{n} numbers"
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise IKSetupError(
            f"{what} must be {n} finite numbers in metres as {form} (e.g. "
            f"{','.join(['0.3'] * n)}); got {text!r}"
        )
    return values


def parse_target(text: str) -> tuple[str, tuple[float, float, float]]:
    """``"frame=X,Y,Z"`` -> (frame, (x, y, z)); IKSetupError if malformed."""
    name, sep, vec = text.partition("=")
    if not sep or not name.strip():
        raise IKSetupError(f"--target must look like FRAME=X,Y,Z (e.g. left_palm=0.3,0.2,0.9); "
                           f"got {text!r}")
    xyz = parse_vector(vec, 3, f"--target {name.strip()}")
    return name.strip(), (xyz[0], xyz[1], xyz[2])


def ik(robot: str, target: list[str] | None = None, com: str | None = None, backend: str = "qp",
       tol: float = 1e-3, max_iters: int = 50, solver: str = "daqp", relative: bool = False,
       keyframe: str | None = None, scene: str | None = None, model_dir: str | None = None,
       root: list[str] | None = None) -> IKParams:
    """``mbctl ik``: each target FRAME=X,Y,Z in m, com X,Y in m, tol in m.

    Raises:
        IKSetupError: A malformed target or CoM.
    """
    return IKParams(
        robot=robot,
        targets=tuple(parse_target(t) for t in (target or [])),
        com_xy=tuple(parse_vector(com, 2, "--com")) if com is not None else None,  # type: ignore[arg-type]
        relative=relative,
        tol_m=tol,
        max_iters=max_iters,
        solver=solver,
        backend=backend,
        keyframe=keyframe,
        scene=scene,
        model_dir=model_dir,
        roots=tuple(root or ()),
    )


def excite(robot: str, duration: float | None = None, seed: int = 0, period: float = 5.0, harmonics: int = 5,
           gravity: bool = True, scene: str | None = None, model_dir: str | None = None,
           payload: str | None = None, plant_error: float = 0.0,
           controller_model: str | None = None) -> ExciteParams:
    """``mbctl excite``: duration and period in s; plant options (payload KG@BODY[:X,Y,Z], %, MJCF)."""
    return ExciteParams(robot, duration, seed, period, harmonics, gravity, scene, model_dir,
                        PlantOptions(payload, plant_error, controller_model))


def identify(runs: list[str], robot: str | None = None, bodies: str | None = None, friction: bool = False,
             armature: bool = False, contact: str = "projected", cutoff_hz: float = 10.0,
             rate_hz: float = 100.0, validation: float = 0.25, torque_noise: float = 0.0,
             encoder_noise: float = 0.0, seed: int = 0, model_dir: str | None = None) -> IdentifyParams:
    """``mbctl identify``: bodies comma-separated; cutoff and rate in Hz (0: off); noise in % and rad."""
    names = tuple(b.strip() for b in (bodies or "").split(",") if b.strip())
    return IdentifyParams(tuple(runs), robot, names, friction, armature, contact, cutoff_hz, rate_hz,
                          validation, torque_noise, encoder_noise, seed, model_dir)
