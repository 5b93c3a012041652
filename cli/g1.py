"""CLI: ``mbctl g1-stand``, ``mbctl g1-track``, ``mbctl g1-arm-pd`` — control jobs on the G1."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from mbctl.jobs.g1 import g1_arm_pd, g1_stand, g1_track

Output = Annotated[Path | None, typer.Option(help="Output directory (default out/<command>).")]


def stand(
    duration: Annotated[float, typer.Option(help="Simulated time (s).")] = 10.0,
    omega: Annotated[float, typer.Option(help="Closed-loop natural frequency (rad/s).")] = 10.0,
    zeta: Annotated[float, typer.Option(help="Damping ratio.")] = 1.0,
    output: Output = None,
) -> None:
    """Stand on the floor under PD + gravity compensation in torque mode; report pelvis drift."""
    result = g1_stand(duration, output or Path("out/g1_stand"), omega_rad_s=omega, zeta=zeta)
    typer.echo(result.summary())
    if result.values["fell"]:
        raise typer.Exit(1)


def track(
    duration: Annotated[
        float | None, typer.Option(help="Simulated time (s) (default: whole trajectory).")
    ] = None,
    omega: Annotated[float, typer.Option(help="Closed-loop natural frequency (rad/s).")] = 40.0,
    zeta: Annotated[float, typer.Option(help="Damping ratio.")] = 1.0,
    output: Output = None,
) -> None:
    """Computed torque on the welded-base G1 along ruckig trajectories (arms, legs, waist)."""
    result = g1_track(duration, output or Path("out/g1_track"), omega_rad_s=omega, zeta=zeta)
    typer.echo(result.summary())


def arm_pd(
    duration: Annotated[
        float | None, typer.Option(help="Simulated time (s) (default: whole trajectory).")
    ] = None,
    side: Annotated[str, typer.Option(help="left or right arm.")] = "left",
    no_gravity_feedforward: Annotated[
        bool, typer.Option("--no-gravity-feedforward", help="Targets without the g(q)/kp offset.")
    ] = False,
    output: Output = None,
) -> None:
    """One arm follows a ruckig trajectory through the Menagerie position actuators."""
    result = g1_arm_pd(duration, output or Path("out/g1_arm_pd"), side=side,
                       gravity_feedforward=not no_gravity_feedforward)
    typer.echo(result.summary())


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("g1-stand")(stand)
    app.command("g1-track")(track)
    app.command("g1-arm-pd")(arm_pd)
