"""The plant options the G1 commands share: the interface, the DDS domain and network interface, the link."""

from __future__ import annotations

import functools
import inspect
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from mbctl.cli._run import ControllerModelOpt, PayloadOpt, PlantErrorOpt

#: The DDS client's defaults, as mbctl.hardware.unitree_hg has them (the help imports no numpy;
#: tests/hardware/test_lowstate.py checks they agree).
WATCHDOG_PERIODS = 25
CONNECT_TIMEOUT_S = 1.0

InterfaceOpt = Annotated[str, typer.Option("--interface", help="sim (in-process) or dds (the G1's low-level "
                                                               "DDS: a robot or `mbctl serve g1`).")]
DomainOpt = Annotated[int, typer.Option("--domain", help="DDS domain id (the robot's is 0).")]
NetworkOpt = Annotated[str, typer.Option("--network-interface", help="Network interface for DDS (default "
                                                                     "lo; name the robot's, e.g. enp3s0).")]
LatencyOpt = Annotated[float, typer.Option("--latency-ms", help="Link delay each direction (ms).")]
JitterOpt = Annotated[float, typer.Option("--jitter-ms", help="Extra delay, uniform in [0, J] (ms).")]
DropOpt = Annotated[float, typer.Option("--drop", help="Probability of losing a message, each direction.")]
ImuNoiseOpt = Annotated[float, typer.Option("--imu-noise", help="Gyro and accelerometer noise, a multiple of "
                                                                "the model's declared sensor noise.")]
SeedOpt = Annotated[int, typer.Option("--seed", help="Seed of the link's drops, jitter and noise.")]
LinkSeedOpt = Annotated[int, typer.Option("--link-seed", help="Seed of the in-process link's drops, jitter "
                                                              "and noise.")]
EstimateOpt = Annotated[bool, typer.Option("--estimate", help="In-process: base position and velocity from "
                                                              "the leg-kinematics estimator, as over DDS.")]
TruthOpt = Annotated[Path | None, typer.Option("--truth", help="DDS: the bridge's truth.csv, to check the "
                                                               "run against the plant.")]
WatchdogOpt = Annotated[int, typer.Option("--watchdog-periods", help="DDS: periods without a state before "
                                                                     "the link counts as lost.")]
DryRunOpt = Annotated[bool, typer.Option("--dry-run", help="DDS: read and print the robot's state; never "
                                                           "command it.")]
StateCrcOpt = Annotated[str, typer.Option(
    "--state-crc", help="DDS: on (the real G1 signs its states) or off: accept states with CRC 0 unchecked "
                        "(Unitree's simulator leaves it 0).")]
RateOpt = Annotated[float | None, typer.Option(
    "--rate-hz", help="DDS: the robot's state rate (Hz), which paces the loop; default: measured at "
                      "connect.")]
WaitOpt = Annotated[float, typer.Option(
    "--wait-s", help="DDS: how long to wait for the robot's state stream (s), e.g. for a bridge still "
                     "loading.")]
MotorGainsOpt = Annotated[str, typer.Option(
    "--motor-gains", help="DDS: stable (the position and damping gains checked against the state period, "
                          "lowered where a motor law applied once per period, as Unitree's simulator does, "
                          "would not keep them stable; each one said in the report) or as-given.")]
DdsConfigOpt = Annotated[Path | None, typer.Option(
    "--dds-config", help="DDS: a Cyclone DDS configuration file of yours, used as written (default: mbctl's "
                         "for the network interface).")]


def _params(*spec: tuple[str, Any, Any]) -> tuple[inspect.Parameter, ...]:
    return tuple(inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=opt)
                 for name, opt, default in spec)


#: ``--interface`` and the link: the G1 jobs that can run on the robot (g1-stand, g1-arm-pd, g1-wbc).
PLANT_PARAMETERS = _params(
    ("interface", InterfaceOpt, "sim"), ("domain", DomainOpt, 0), ("network_interface", NetworkOpt, "lo"),
    ("latency_ms", LatencyOpt, 0.0), ("jitter_ms", JitterOpt, 0.0), ("drop", DropOpt, 0.0),
    ("imu_noise", ImuNoiseOpt, 0.0), ("estimate", EstimateOpt, False), ("link_seed", LinkSeedOpt, 0),
    ("truth", TruthOpt, None), ("watchdog_periods", WatchdogOpt, WATCHDOG_PERIODS),
    ("dry_run", DryRunOpt, False),
    ("state_crc", StateCrcOpt, "on"), ("rate_hz", RateOpt, None), ("wait_s", WaitOpt, CONNECT_TIMEOUT_S),
    ("dds_config", DdsConfigOpt, None), ("motor_gains", MotorGainsOpt, "stable"))

#: ``--payload``, ``--plant-error``, ``--controller-model``: every simulating job.
MODEL_PARAMETERS = _params(("payload", PayloadOpt, None), ("plant_error", PlantErrorOpt, 0.0),
                           ("controller_model", ControllerModelOpt, None))


Command = Callable[..., None]


def with_options(*groups: tuple[inspect.Parameter, ...]) -> Callable[[Command], Command]:
    """Add option groups to a command, before its ``--output``; they reach it as one dict ``extra``.

    One definition per option: the commands that share the plant or model options take them from
    here (typer reads the wrapper's signature), and pass ``**extra`` on to the job's options.
    """
    added = tuple(p for group in groups for p in group)

    def decorate(command: Command) -> Command:
        own = [p for p in inspect.signature(command).parameters.values() if p.name != "extra"]
        cut = next(i for i, p in enumerate(own) if p.name == "output")
        names = [p.name for p in added]

        @functools.wraps(command)
        def wrapper(**kwargs: Any) -> None:
            extra = {name: kwargs.pop(name) for name in names}
            command(**kwargs, extra=extra)

        hints = typing.get_type_hints(command, include_extras=True)
        hints.pop("extra", None)
        wrapper.__annotations__ = {**hints, **{p.name: p.annotation for p in added}}
        wrapper.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
            [p.replace(kind=inspect.Parameter.KEYWORD_ONLY, annotation=hints.get(p.name, p.annotation))
             for p in (*own[:cut], *added, *own[cut:])])
        return wrapper

    return decorate
