"""The ``mbctl`` command line. Each command module registers its commands on ``app``."""

from __future__ import annotations

import inspect
import sys
from typing import Annotated

import typer

from mbctl.exceptions import ToolkitError

app = typer.Typer(
    name="mbctl",
    help=(
        "Model-based robot control: Pinocchio models, MuJoCo plants, cross-checked.\n\n"
        "Exit codes: 0 success; 1 a result outside its bound (xcheck FAIL, IK not converged, robot "
        "fell, tracking bound missed, simulation diverged); 2 bad input, usage or IO; 130 interrupted."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _register_commands() -> None:
    # One module per command family; each exposes register(app). Imported here, not at module
    # top, so `mbctl --help` stays fast and a broken family names itself in the traceback.
    from mbctl.cli import demo, g1, g1_walk, g1_wbc, ik, robots, serve, sim, sweep, view, xcheck
    from mbctl.cli import identify as identification

    for family in (robots, sim, demo, g1, g1_wbc, g1_walk, xcheck, ik, sweep, view, serve, identification):
        family.register(app)
    for command in app.registered_commands:
        command.help = one_line_paragraphs(command.help or inspect.getdoc(command.callback) or "")


def one_line_paragraphs(text: str) -> str:
    """``text``'s paragraphs each on one line.

    Typer (0.29) prints a description's later paragraphs with their source line breaks, which the
    terminal then wraps again (ragged lines at 80 columns).
    """
    return "\n\n".join(" ".join(p.splitlines()) for p in inspect.cleandoc(text).split("\n\n"))


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        typer.echo(f"mbctl {version('mbctl')}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
    cpus: Annotated[
        str | None,
        typer.Option("--cpus", help="Run the command on these CPU cores only, e.g. 0 or 0,2-3 (Linux; before "
                                    "the command's name): a DDS job and `mbctl serve g1` each on its own "
                                    "core, as on a robot's computer."),
    ] = None,
) -> None:
    """Options that apply before any command (the help text is the app's)."""
    if cpus is not None:
        from mbctl.jobs.cpus import pin_process

        pin_process(cpus)  # before any thread starts: every later one inherits the cores


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``message`` to stderr and return an Exit to raise with ``code``."""
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(code)


def _wants_rendering(argv: list[str]) -> bool:
    """Whether the command renders offscreen (render, replay --video, any --video)."""
    return "--video" in argv or bool(argv) and argv[0] == "render"


def main() -> None:
    """Console-script entry point: toolkit errors exit 2 with their message, no traceback."""
    # MuJoCo reads MUJOCO_GL when first imported: pick a headless backend before that, or switch
    # OpenGL off for the commands that do not render (a bad MUJOCO_GL then breaks none of them).
    from mbctl.gl import VideoError, choose_gl_backend, disable_gl

    if _wants_rendering(sys.argv[1:]) and "--help" not in sys.argv:
        try:
            choose_gl_backend()
        except VideoError as exc:
            typer.echo(f"error: {exc}", err=True)
            sys.exit(2)
    else:
        disable_gl()
    _register_commands()
    try:
        app()
    except ToolkitError as exc:  # commands raise toolkit errors; users see the message only
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except KeyboardInterrupt:  # before a job's runner took over (loading, parsing)
        typer.echo("interrupted", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
