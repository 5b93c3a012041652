"""What ``mbctl ik`` reports: the verdict (converged, or why not), ``ik_pose.json`` and the summary lines."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from mbctl.control.ik import IKResult, WholeBodyIK, joint_positions_by_name
from mbctl.control.tasks import TaskResidual, Tolerance, converged, residual_table
from mbctl.jobs.ik_params import IKParams
from mbctl.jobs.ik_plant import PathCollisions, PlantResiduals
from mbctl.robots.model_pair import Robot


class Verdict(NamedTuple):
    """Whether the run converged, and the one-line status that says why or why not.

    Attributes:
        converged: IK residuals, plant residuals and the collision check all passed.
        collision_free: Every checked pair stayed at or above the minimum distance on the whole
            path; None when no pair is checked (an unchecked claim is never True).
        status: The status phrase of the summary's first line.
    """

    converged: bool
    collision_free: bool | None
    status: str

    @classmethod
    def of(cls, res: IKResult, plant: PlantResiduals, collisions: PathCollisions | None, params: IKParams,
           blocked_within_m: float) -> Verdict:
        """Judge a solve: the IK's own residuals, the plant's, the body's distances on the path."""
        clear = None if collisions is None else collisions.clear_of(params.min_distance_m)
        on_plant = converged(plant.task_residuals(), _tolerance(params))
        if res.converged and on_plant and clear is not False:
            return cls(True, clear, "converged")
        if res.converged and not on_plant:
            return cls(False, clear, "NOT converged (the MuJoCo plant disagrees with the IK's model)")
        if clear is False and collisions is not None:
            where = (f"pair {collisions.closest_pair} at {collisions.min_distance_m * 1e3:.1f} mm at step "
                     f"{collisions.closest_step}, minimum {params.min_distance_m * 1e3:g} mm")
            if not params.avoids:
                return cls(False, clear, f"NOT converged: the path goes through the body ({where}); "
                                         "give --avoid-collisions")
            if collisions.closest_step == 0:
                return cls(False, clear, f"NOT converged: the start is already in collision ({where})")
            return cls(False, clear, f"NOT converged: collision avoidance did not hold ({where})")
        if (res.stalled and params.avoids and collisions is not None
                and collisions.distances_m[-1] <= params.min_distance_m + blocked_within_m):
            return cls(False, clear, "blocked by collision avoidance: the targets cannot be reached without "
                                     f"collision (pair {collisions.pairs[-1]} held at "
                                     f"{collisions.distances_m[-1] * 1e3:.1f} mm); the pose written is the "
                                     "closest collision-free one")
        if res.stalled:
            return cls(False, clear, "stalled: the step vanished (the target is out of reach, or the start "
                                     "pose is singular for it: try another --keyframe)")
        return cls(False, clear, "NOT converged (iteration cap)")


def _tolerance(params: IKParams) -> Tolerance:
    """The run's tolerances: the IK's residuals and the plant's are judged by the same rule."""
    return Tolerance(params.tol_m, params.tol_rad)


def _levels(res: IKResult) -> list[dict[str, Any]]:
    return [{"tasks": list(names), "residual": residual.as_dict()}
            for names, residual in zip(res.levels, res.level_residuals, strict=True)]


def payload(robot: Robot, ik: WholeBodyIK, params: IKParams, task_set: str, start: str,
            clipped: dict[str, float], res: IKResult, plant: PlantResiduals,
            collisions: PathCollisions | None, margins: dict[str, tuple[float, float]],
            verdict: Verdict) -> dict[str, Any]:
    """The content of ``ik_pose.json`` (its keys are also the report's values)."""
    per_iteration_s = float(np.median(res.iteration_times_s)) if res.iterations else None
    targets = {s.frame: {"position": list(s.position) if s.position is not None else None,
                         "quat_wxyz": list(s.quat_wxyz) if s.quat_wxyz is not None else None,
                         "reference": s.reference} for s in params.specs}
    return {
        "robot": robot.name,
        "origin": robot.source.origin,
        "task_set": task_set,
        "backend": params.backend,
        "solver": params.solver,
        "start": start,
        "clipped_start": clipped,
        "convention": "Pinocchio (free joint: x, y, z, qx, qy, qz, qw)",
        "converged": verdict.converged,
        "status": verdict.status,
        "ik_converged": bool(res.converged),
        "stalled": bool(res.stalled),
        "iterations": res.iterations,
        "wall_time_s": res.wall_time_s,
        "median_iteration_time_s": per_iteration_s,
        "tolerance_m": params.tol_m,
        "tolerance_rad": params.tol_rad,
        "targets": targets,
        "targets_relative": params.relative,
        "com": list(params.com_xy) if params.com_xy is not None else None,
        "priorities": dict(params.priorities),
        "unnamed_tasks_level": (len(res.levels) - 1) if params.priorities else None,
        "levels": _levels(res),
        "residuals": residual_table(res.residuals),
        "plant_residual_m": plant.position_m,
        "plant_residual_rad": plant.orientation_rad,
        "min_joint_limit_margin": min((min(v) for v in margins.values()), default=None),
        "collision_avoidance": params.avoids,
        "collision_pairs_checked": collisions.n_pairs if collisions is not None else 0,
        "min_distance_bound_m": params.min_distance_m,
        "min_distance_m": collisions.min_distance_m if collisions is not None else None,
        "closest_pair": collisions.closest_pair if collisions is not None else None,
        "closest_pair_step": collisions.closest_step if collisions is not None else None,
        "collision_free": verdict.collision_free,
        "path_min_distance_m": collisions.distances_m.tolist() if collisions is not None else None,
        "q": joint_positions_by_name(robot, res.q),
        "model_edits": list(robot.source.edits),
    }


def _clipped(clipped: dict[str, float]) -> str:
    return ", ".join(f"{joint} by {d:.4f}" for joint, d in clipped.items())


def _unit(key: str) -> tuple[str, str]:
    name, unit = key.split(" ")
    return name, unit.replace("[", "(").replace("]", ")")


def summary(name: str, task_set: str, start: str, clipped: dict[str, float], params: IKParams, res: IKResult,
            plant: PlantResiduals, collisions: PathCollisions | None, margins: dict[str, tuple[float, float]],
            verdict: Verdict) -> list[str]:
    """The run's summary lines (printed and kept in the report)."""
    per_it = float(np.median(res.iteration_times_s)) if res.iterations else 0.0
    lines = [f"robot {name} ({task_set} task set, backend {params.backend}, solver {params.solver}, tol "
             f"{params.tol_m:g} m): {res.iterations} iterations, {res.wall_time_s * 1e3:.1f} ms "
             f"({per_it * 1e6:.0f} us/iteration median)",
             f"result: {verdict.status}",
             f"start: {start}" + (f", clipped into the joint limits ({_clipped(clipped)})"
                                  if clipped else ""),
             "task residuals (IK's own; plant = measured in MuJoCo):"]
    for task, residual in res.residuals.items():
        text = ", ".join(f"{_unit(k)[0]} {v:.3e} {_unit(k)[1]}" for k, v in residual.as_dict().items())
        plant_text = [f"{plant.position_m[task]:.3e} (m)"] if task in plant.position_m else []
        if task in plant.orientation_rad:
            plant_text.append(f"{plant.orientation_rad[task]:.3e} (rad)")
        if plant_text:
            text += ", plant " + ", ".join(plant_text)
        note = "  (regulariser, not a target)" if residual.regularising else ""
        lines.append(f"  {task:20s} {text}{note}")
    if len(res.levels) > 1:
        last = len(res.levels) - 1
        lines.append(f"priority levels (0 first; tasks not named by --priority at level {last}, the last; "
                     "each level's largest residual):")
        for k, (names, residual) in enumerate(zip(res.levels, res.level_residuals, strict=True)):
            text = ", ".join(f"{_unit(key)[0]} {v:.3e} {_unit(key)[1]}"
                             for key, v in residual.as_dict().items())
            lines.append(f"  level {k}: {', '.join(names)}: {text}")
    closest = sorted(margins.items(), key=lambda kv: min(kv[1]))[:5]
    if closest:
        lines.append("joint-limit margins (closest 5; to lower, to upper) (rad or m):")
        lines += [f"  {joint:28s} {lo:+.4f} {hi:+.4f}" for joint, (lo, hi) in closest]
    else:
        lines.append("joint-limit margins: no joint has finite position limits")
    worst = max(plant.position_m.values(), default=0.0)
    worst_rad = max(plant.orientation_rad.values(), default=0.0)
    tolerance = _tolerance(params)
    text = (f"plant check: largest residual in MuJoCo {worst:.3e} m "
            f"({'within' if tolerance.accepts(TaskResidual(position_m=worst)) else 'OUTSIDE'} "
            f"tol {params.tol_m:g} m)")
    if plant.orientation_rad:
        text += (f", {worst_rad:.3e} rad "
                 f"({'within' if tolerance.accepts(TaskResidual(orientation_rad=worst_rad)) else 'OUTSIDE'} "
                 f"tol {params.tol_rad:g} rad)")
    lines.append(text)
    if collisions is None:
        lines.append("collision check: none (give --avoid-collisions or --collision-pair)")
    else:
        ok = "at or above" if verdict.collision_free else "BELOW"
        lines.append(f"collision check ({collisions.n_pairs} geom pairs at each of the "
                     f"{len(collisions.distances_m)} configurations of the path, MuJoCo mj_geomDistance): "
                     f"closest {collisions.closest_pair} at {collisions.min_distance_m * 1e3:.2f} mm (step "
                     f"{collisions.closest_step}), {ok} the minimum {params.min_distance_m * 1e3:g} mm; "
                     f"avoidance {'on' if params.avoids else 'off'}")
    return lines
