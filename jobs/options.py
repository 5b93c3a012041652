"""Each job's parameters from its command-line options, named as the options are.

One function per job takes the CLI's option values (the option name with dashes as
underscores: ``--model-error`` is ``model_error``, in the CLI's units) and returns the job's
frozen parameter dataclass. The CLI commands call these functions, and ``mbctl sweep`` reads
their signatures (names, types, defaults) to parse ``--param NAME=V1,V2``, so the command line and
the sweep cannot disagree on a name, a unit or a default. ``tests/cli`` checks that every
command's signature matches its function here.

Only parsing and unit conversion live here; validation stays in the dataclasses (except the
duration limit of the G1 jobs, checked here: ``mbctl.limits``).
"""

from __future__ import annotations

from pathlib import Path

from mbctl.hardware.dds_options import CONNECT_TIMEOUT_S, WATCHDOG_PERIODS
from mbctl.jobs import ik_params
from mbctl.jobs.demo import DemoConfig
from mbctl.jobs.excite import ExciteParams
from mbctl.jobs.g1 import ArmPDParams, StandParams, TrackParams
from mbctl.jobs.g1_wbc import WBCParams
from mbctl.jobs.identify import IdentifyParams
from mbctl.jobs.ik_params import IKParams
from mbctl.jobs.joint_step import JointStepParams
from mbctl.jobs.model_options import ModelOptions
from mbctl.jobs.plant import PlantOptions
from mbctl.jobs.serve import ServeParams
from mbctl.jobs.workspace import WorkspaceParams
from mbctl.jobs.xcheck import XcheckParams
from mbctl.robots.joint_pairing import parse_joint_map


def demo(controller: str = "ct", compare: bool = False, model_error: float = 0.0,
         duration: float | None = None, side: float = 0.2, speed: float = 0.5, omega: float = 30.0,
         gravity: bool = True, max_rms_mm: float | None = None, payload: str | None = None,
         plant_error: float = 0.0, controller_model: str | None = None) -> DemoConfig:
    """``mbctl demo``: model_error in %, duration in s, side in m, speed in m/s, omega in rad/s, mm.

    The model options: payload KG@BODY[:X,Y,Z], plant_error in %, controller_model an MJCF file.
    """
    return DemoConfig(controller=controller, side_m=side, max_speed_m_s=speed, omega_rad_s=omega,
                      duration_s=duration, model_error_pct=model_error, gravity=gravity, compare=compare,
                      max_rms_error_m=None if max_rms_mm is None else max_rms_mm * 1e-3,
                      models=ModelOptions(payload, plant_error, controller_model))


def g1_stand(duration: float = 10.0, omega: float = 10.0, zeta: float = 1.0,
             model_dir: str | None = None, interface: str = "sim", domain: int = 0,
             network_interface: str = "lo", latency_ms: float = 0.0, jitter_ms: float = 0.0,
             drop: float = 0.0, imu_noise: float = 0.0, estimate: bool = False, link_seed: int = 0,
             truth: Path | None = None, watchdog_periods: int = WATCHDOG_PERIODS, dry_run: bool = False,
             state_crc: str = "on", rate_hz: float | None = None, wait_s: float = CONNECT_TIMEOUT_S,
             dds_config: Path | None = None, motor_gains: str = "stable",
             payload: str | None = None, plant_error: float = 0.0,
             controller_model: str | None = None) -> StandParams:
    """``mbctl g1-stand``: duration in s, omega in rad/s, zeta (-); the plant and model options."""
    return StandParams(duration, omega, zeta, model_dir, plant(
        interface, domain, network_interface, latency_ms, jitter_ms, drop, imu_noise, estimate, link_seed,
        truth, watchdog_periods, dry_run, state_crc, rate_hz, wait_s, dds_config, motor_gains),
        ModelOptions(payload, plant_error, controller_model))


def g1_track(duration: float | None = None, omega: float = 40.0, zeta: float = 1.0,
             max_rms_rad: float | None = None, model_dir: str | None = None, payload: str | None = None,
             plant_error: float = 0.0, controller_model: str | None = None) -> TrackParams:
    """``mbctl g1-track``: duration in s, omega in rad/s, zeta (-), max_rms_rad in rad; model options."""
    return TrackParams(duration, omega, zeta, max_rms_rad, model_dir,
                       ModelOptions(payload, plant_error, controller_model))


def g1_arm_pd(duration: float | None = None, side: str = "left", gravity_feedforward: bool = True,
              max_rms_rad: float | None = None, model_dir: str | None = None, interface: str = "sim",
              domain: int = 0, network_interface: str = "lo", latency_ms: float = 0.0, jitter_ms: float = 0.0,
              drop: float = 0.0, imu_noise: float = 0.0, estimate: bool = False, link_seed: int = 0,
              truth: Path | None = None, watchdog_periods: int = WATCHDOG_PERIODS, dry_run: bool = False,
              state_crc: str = "on", rate_hz: float | None = None, wait_s: float = CONNECT_TIMEOUT_S,
              dds_config: Path | None = None, motor_gains: str = "stable",
              payload: str | None = None, plant_error: float = 0.0,
              controller_model: str | None = None) -> ArmPDParams:
    """``mbctl g1-arm-pd``: duration in s, side left or right, max_rms_rad in rad; plant and model options."""
    return ArmPDParams(duration, side, gravity_feedforward, max_rms_rad, model_dir, plant(
        interface, domain, network_interface, latency_ms, jitter_ms, drop, imu_noise, estimate, link_seed,
        truth, watchdog_periods, dry_run, state_crc, rate_hz, wait_s, dds_config, motor_gains),
        ModelOptions(payload, plant_error, controller_model))


def plant(interface: str = "sim", domain: int = 0, network_interface: str = "lo", latency_ms: float = 0.0,
          jitter_ms: float = 0.0, drop: float = 0.0, imu_noise: float = 0.0, estimate: bool = False,
          link_seed: int = 0, truth: Path | None = None, watchdog_periods: int = WATCHDOG_PERIODS,
          dry_run: bool = False, state_crc: str = "on", rate_hz: float | None = None,
          wait_s: float = CONNECT_TIMEOUT_S, dds_config: Path | None = None,
          motor_gains: str = "stable") -> PlantOptions:
    """The plant options of the G1 jobs: latency and jitter in ms, drop a probability, imu_noise a factor.

    ``link_seed`` (not ``seed``: a sweep's ``--seeds`` is for jobs that always draw random numbers)
    seeds the in-process link's drops, jitter and noise. Over DDS: ``state_crc`` on or off, ``rate_hz``
    in Hz (None: measured), ``wait_s`` in s, ``dds_config`` a Cyclone configuration file, ``motor_gains``
    stable or as-given.
    """
    return PlantOptions(interface, domain, network_interface, latency_ms, jitter_ms, drop, imu_noise,
                        estimate, link_seed, None if truth is None else str(truth), watchdog_periods, dry_run,
                        state_crc, rate_hz, wait_s, None if dds_config is None else str(dds_config),
                        motor_gains)


def serve(robot: str = "g1", start: str = "stand", domain: int = 0, network_interface: str = "lo",
          latency_ms: float = 0.0, jitter_ms: float = 0.0, drop: float = 0.0, imu_noise: float = 0.0,
          seed: int = 0, duration: float | None = None, idle_timeout: float | None = None,
          model_dir: str | None = None, lockstep: bool = False) -> ServeParams:
    """``mbctl serve``: latency and jitter in ms, drop a probability, duration and idle_timeout in s."""
    return ServeParams(robot, start, domain, network_interface, latency_ms, jitter_ms, drop, imu_noise, seed,
                       duration, idle_timeout, model_dir, lockstep)


def g1_wbc(scenario: str = "stand", duration: float | None = None, impulse: float | None = None,
           direction: float | None = None, model_error: float = 0.0, model_dir: str | None = None,
           interface: str = "sim", domain: int = 0, network_interface: str = "lo", latency_ms: float = 0.0,
           jitter_ms: float = 0.0, drop: float = 0.0, imu_noise: float = 0.0, estimate: bool = False,
           link_seed: int = 0, truth: Path | None = None, watchdog_periods: int = WATCHDOG_PERIODS,
           dry_run: bool = False, state_crc: str = "on", rate_hz: float | None = None,
           wait_s: float = CONNECT_TIMEOUT_S, dds_config: Path | None = None, motor_gains: str = "stable",
           payload: str | None = None, plant_error: float = 0.0,
           controller_model: str | None = None) -> WBCParams:
    """``mbctl g1-wbc``: duration in s, impulse in N s, direction in deg, model_error %; plant options."""
    return WBCParams(scenario, duration, impulse, direction, model_error, model_dir, plant(
        interface, domain, network_interface, latency_ms, jitter_ms, drop, imu_noise, estimate, link_seed,
        truth, watchdog_periods, dry_run, state_crc, rate_hz, wait_s, dds_config, motor_gains),
        ModelOptions(payload, plant_error, controller_model))


def joint_step(robot: str, joint: str, delta: float, steps: int = 250, keyframe: str | None = None,
               sensor: list[str] | None = None, scene: str | None = None,
               model_dir: str | None = None, payload: str | None = None, plant_error: float = 0.0,
               controller_model: str | None = None) -> JointStepParams:
    """``mbctl joint-step``: delta in rad (m for a slide joint), steps of the physics; model options."""
    return JointStepParams(robot, joint, delta, steps, keyframe, tuple(sensor or ()), scene, model_dir,
                           ModelOptions(payload, plant_error, controller_model))


def xcheck(robot: str, scene: str | None = None, states: int = 100, seed: int = 0,
           json_path: Path | None = None, pin_model: Path | None = None, gravity: bool = False,
           model_dir: str | None = None, analytic: str = "mujoco",
           root: list[str] | None = None, joint_map: str | None = None,
           floating_base: bool | None = None) -> XcheckParams:
    """``mbctl xcheck``: states random states drawn from seed; root bodies select the robot's trees.

    ``joint_map`` is ``A=B,...`` or a file of such lines (``robots.joint_pairing.parse_joint_map``).
    """
    return XcheckParams(robot, scene, states, seed, json_path, pin_model, gravity, model_dir, analytic,
                        tuple(root or ()), tuple(parse_joint_map(joint_map).items()) if joint_map else (),
                        floating_base)


def workspace(robot: str = "two_link", samples: int = 121) -> WorkspaceParams:
    """``mbctl workspace``: samples per joint."""
    return WorkspaceParams(robot, samples)


def ik(robot: str, target: list[str] | None = None, com: str | None = None, backend: str = "qp",
       tol: float = 1e-3, max_iters: int = 50, solver: str = "daqp", relative: bool = False,
       keyframe: str | None = None, scene: str | None = None, model_dir: str | None = None,
       root: list[str] | None = None, orientation: list[str] | None = None,
       priority: list[str] | None = None, avoid_collisions: bool = False,
       collision_pair: list[str] | None = None, min_distance: float = 0.005,
       max_velocity: list[str] | None = None, damping: float = 0.0, clip_start: bool = False) -> IKParams:
    """``mbctl ik``: targets in m (and quaternions), com in m, tol and min_distance in m.

    Targets FRAME[@REF]=X,Y,Z[,QW,QX,QY,QZ], com X,Y[,Z], max_velocity JOINT=SPEED in rad/s,
    priority NAME=LEVEL, damping a weight.

    Raises:
        IKSetupError: A malformed target, orientation, CoM, priority or velocity.
    """
    specs = [ik_params.parse_target(t) for t in (target or [])]
    return IKParams(
        robot=robot,
        com_xy=ik_params.parse_numbers(com, (2, 3), "--com (m)", "X,Y or X,Y,Z") if com is not None else None,
        relative=relative,
        tol_m=tol,
        max_iters=max_iters,
        solver=solver,
        backend=backend,
        keyframe=keyframe,
        scene=scene,
        model_dir=model_dir,
        roots=tuple(root or ()),
        poses=(*specs, *(ik_params.parse_orientation(o) for o in (orientation or []))),
        priorities=tuple(ik_params.parse_priority(p) for p in (priority or [])),
        avoid_collisions=avoid_collisions,
        collision_pairs=tuple(collision_pair or ()),
        min_distance_m=min_distance,
        max_velocities=tuple(ik_params.parse_velocity(v) for v in (max_velocity or [])),
        damping_cost=damping,
        clip_start=clip_start,
    )


def excite(robot: str, duration: float | None = None, seed: int = 0, period: float = 5.0, harmonics: int = 5,
           gravity: bool = True, scene: str | None = None, model_dir: str | None = None,
           interface: str = "sim", domain: int = 0, network_interface: str = "lo", latency_ms: float = 0.0,
           jitter_ms: float = 0.0, drop: float = 0.0, imu_noise: float = 0.0, estimate: bool = False,
           link_seed: int = 0, truth: Path | None = None, watchdog_periods: int = WATCHDOG_PERIODS,
           dry_run: bool = False, state_crc: str = "on", rate_hz: float | None = None,
           wait_s: float = CONNECT_TIMEOUT_S, dds_config: Path | None = None, motor_gains: str = "stable",
           payload: str | None = None, plant_error: float = 0.0,
           controller_model: str | None = None) -> ExciteParams:
    """``mbctl excite``: duration and period in s; the plant options (the G1); model options (as demo)."""
    return ExciteParams(robot, duration, seed, period, harmonics, gravity, scene, model_dir,
                        ModelOptions(payload, plant_error, controller_model), plant(
                            interface, domain, network_interface, latency_ms, jitter_ms, drop, imu_noise,
                            estimate, link_seed, truth, watchdog_periods, dry_run, state_crc, rate_hz, wait_s,
                            dds_config, motor_gains))


def identify(runs: list[str], robot: str | None = None, bodies: str | None = None, friction: bool = False,
             armature: bool = False, contact: str = "projected", cutoff_hz: float = 10.0,
             rate_hz: float = 100.0, validation: float = 0.25, torque_noise: float = 0.0,
             encoder_noise: float = 0.0, seed: int = 0, model_dir: str | None = None) -> IdentifyParams:
    """``mbctl identify``: bodies comma-separated; cutoff and rate in Hz (0: off); noise in % and rad."""
    names = tuple(b.strip() for b in (bodies or "").split(",") if b.strip())
    return IdentifyParams(tuple(runs), robot, names, friction, armature, contact, cutoff_hz, rate_hz,
                          validation, torque_noise, encoder_noise, seed, model_dir)
