"""The plant options the G1 commands share: the interface, the DDS domain and network interface, the link."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

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
