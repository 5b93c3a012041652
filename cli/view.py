"""CLI: ``mbctl render``, ``mbctl replay``, ``mbctl view`` — look at robots and recorded runs."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, BinaryIO, cast

import typer

from mbctl.cli.robots import ModelDirOpt, RobotArg, SceneOpt

if TYPE_CHECKING:  # the commands import MuJoCo and the jobs when they run, not for --help
    import mujoco

    from mbctl.robots.model_pair import Robot
    from mbctl.sim.video import VideoError

SizeOpt = Annotated[str, typer.Option("--size", help="Image or video frame size WIDTHxHEIGHT (px).")]
KeyframeOpt = Annotated[
    str | None, typer.Option("--keyframe", help="Keyframe to show (default: the model's qpos0).")
]
WebOpt = Annotated[bool, typer.Option(
    "--web", help="Serve a 3-D view to the browser on 127.0.0.1 (no display needed; Ctrl-C stops it).")]
PortOpt = Annotated[int, typer.Option(
    "--port", help="With --web: the loopback TCP port (0: a free one; the URL is printed).")]


def _display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _no_display(what: str) -> VideoError:
    from mbctl.sim.video import VideoError

    return VideoError(
        f"{what} needs a display (DISPLAY or WAYLAND_DISPLAY is not set here); headless, use "
        "`mbctl render ROBOT --output FILE.png` for a still or `mbctl replay RUN_DIR --video` for an MP4"
    )


def _posed(robot: Robot, keyframe: str | None) -> mujoco.MjData:
    import mujoco

    data = mujoco.MjData(robot.mj_model)
    if keyframe is not None:
        mujoco.mj_resetDataKeyframe(robot.mj_model, data, robot.keyframe_id(keyframe))
    mujoco.mj_forward(robot.mj_model, data)
    return data


def render(
    robot: RobotArg,
    output: Annotated[Path, typer.Option("--output", help="PNG file to write.")],
    keyframe: KeyframeOpt = None,
    size: SizeOpt = "640x480",
    scene: SceneOpt = None,
    model_dir: ModelDirOpt = None,
) -> None:
    """Render one still image of ROBOT headless (camera on the base, or framing a fixed robot)."""
    from matplotlib import image

    from mbctl.jobs.runner import OutputError, check_output_file
    from mbctl.robots import load_robot
    from mbctl.sim.atomic import write_bytes_atomic
    from mbctl.sim.trajectory import base_body
    from mbctl.sim.video import VideoSpec, parse_size, still

    if output.suffix.lower() != ".png":
        raise OutputError(f"--output must be a .png file; got {str(output)!r}")
    width, height = parse_size(size)
    check_output_file(output)
    loaded = load_robot(robot, scene, model_dir=model_dir)
    data = _posed(loaded, keyframe)
    frame = still(loaded.mj_model, data, VideoSpec(width, height), base_body(loaded))
    # written beside and renamed: a symbolic link at --output is replaced, never followed
    write_bytes_atomic(output, lambda f: image.imsave(cast(BinaryIO, f), frame, format="png"))
    typer.echo(f"wrote {output} ({width}x{height} px)")


def replay(
    run_dir: Annotated[Path, typer.Argument(help="A run folder (it holds trajectory.npz and model.xml).")],
    video: Annotated[
        bool, typer.Option("--video", help="Render to MP4 headless instead of the viewer.")
    ] = False,
    output: Annotated[
        Path | None, typer.Option("--output", help="MP4 file (default RUN_DIR/replay.mp4).")
    ] = None,
    size: SizeOpt = "640x480",
    web: WebOpt = False,
    port: PortOpt = 0,
) -> None:
    """Play a recorded run back: in MuJoCo's viewer, to an MP4 with --video, or in the browser with --web."""
    from mbctl.jobs.exceptions import JobError
    from mbctl.jobs.runner import OutputError, check_output_file
    from mbctl.sim.trajectory import TRAJECTORY_NAME, load_trajectory
    from mbctl.sim.video import VideoSpec, film_trajectory, parse_size

    if web and (video or output is not None):
        given = " and ".join(o for o, on in (("--video", video), ("--output", output is not None)) if on)
        raise JobError(f"replay --web serves the run to the browser and writes no file; {given} "
                       "(an MP4) cannot go with it: run `mbctl replay RUN_DIR --video` for the MP4, "
                       "and `mbctl replay RUN_DIR --web` for the browser")
    if not (run_dir / TRAJECTORY_NAME).is_file():
        raise OutputError(
            f"{str(run_dir)!r} holds no {TRAJECTORY_NAME}: not a run folder of a simulating job"
        )
    if web:
        from mbctl.jobs.web_view import run_view, serve_until_interrupted

        serve_until_interrupted(lambda: run_view(run_dir, port))
        return
    try:
        model, t, qpos, track = load_trajectory(run_dir)
    except ValueError as exc:
        raise OutputError(f"cannot load the run's model from {str(run_dir)!r}: {exc}") from exc
    if video:
        width, height = parse_size(size)
        path = check_output_file(output or run_dir / "replay.mp4")
        frames = film_trajectory(model, t, qpos, path, VideoSpec(width, height), track)
        typer.echo(f"wrote {path} ({frames} frames, {t[-1] - t[0]:.2f} s simulated)")
        return
    if not _display():
        raise _no_display("replay without --video")
    import mujoco
    import mujoco.viewer

    data = mujoco.MjData(model)
    with mujoco.viewer.launch_passive(model, data) as viewer:
        start = time.perf_counter()
        for ti, q in zip(t, qpos, strict=True):
            if not viewer.is_running():
                break
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            viewer.sync()
            time.sleep(max(0.0, (ti - t[0]) - (time.perf_counter() - start)))


def view(robot: RobotArg, keyframe: KeyframeOpt = None, scene: SceneOpt = None,
         model_dir: ModelDirOpt = None, web: WebOpt = False, port: PortOpt = 0) -> None:
    """Open MuJoCo's interactive viewer on ROBOT (needs a display), or serve it to the browser with --web."""
    from mbctl.robots import load_robot

    if web:
        from mbctl.jobs.web_view import robot_view, serve_until_interrupted

        loaded = load_robot(robot, scene, model_dir=model_dir)
        serve_until_interrupted(lambda: robot_view(loaded, keyframe, port))
        return
    if not _display():
        raise _no_display("mbctl view")
    import mujoco.viewer

    loaded = load_robot(robot, scene, model_dir=model_dir)
    mujoco.viewer.launch(loaded.mj_model, _posed(loaded, keyframe))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("render")(render)
    app.command("replay")(replay)
    app.command("view")(view)
