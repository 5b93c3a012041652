"""Report sections of a run: the environment, the plant's model and settings, the run's counters.

The job runner (``mbctl.jobs.runner``) assembles them with the status and values into
``report.json``.
"""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata
from typing import Any

import mujoco

from mbctl.robots.menagerie import sha256_file
from mbctl.sim.simulator import Simulator

#: Distributions whose versions every report records.
PACKAGES = ("mbctl", "mujoco", "pin", "numpy", "mink", "qpsolvers", "osqp", "daqp", "ruckig",
            "mujoco-menagerie", "matplotlib")


def package_versions() -> dict[str, str]:
    """Installed versions of the packages in ``PACKAGES`` ("absent" when not installed)."""
    out = {}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "absent"
    return out


def environment() -> dict[str, Any]:
    """Python, platform and package versions, and the CPU cores the run could use (``mbctl --cpus``)."""
    return {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpus": sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "packages": package_versions(),
    }


def model_section(sim: Simulator) -> dict[str, Any]:
    """The robot's model files (with SHA-256), edits, sizes and MuJoCo settings."""
    robot, m = sim.robot, sim.model
    return {
        "robot": robot.name,
        "origin": robot.source.origin,
        "files": {
            role: {"path": str(path), "sha256": sha256_file(path)}
            for role, path in robot.source.files().items()
        },
        "load_time_edits": list(robot.source.edits),
        "analytic_model": robot.source.analytic,
        "nq": robot.nq,
        "nv": robot.nv,
        "nu": robot.nu,
        "timestep_s": float(m.opt.timestep),
        "control_period_s": sim.control_period_s,
        "integrator": mujoco.mjtIntegrator(int(m.opt.integrator)).name.removeprefix("mjINT_"),
        "solver": {
            "type": mujoco.mjtSolver(int(m.opt.solver)).name.removeprefix("mjSOL_"),
            "iterations": int(m.opt.iterations),
            "tolerance": float(m.opt.tolerance),
            "ls_iterations": int(m.opt.ls_iterations),
            "cone": mujoco.mjtCone(int(m.opt.cone)).name.removeprefix("mjCONE_"),
        },
        "gravity_m_s2": [float(g) for g in m.opt.gravity],
    }


def run_section(sim: Simulator) -> dict[str, Any]:
    """Steps, simulated time, warning counters, contacts and saturations of the run so far."""
    return {
        "steps": sim.n_steps,
        "simulated_time_s": sim.time_s,
        "warnings": sim.warnings,
        "contact_count": sim.contact_count,
        "saturations": sim.saturations(),
    }
