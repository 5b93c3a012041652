"""The jobs a sweep can run, by command name, with their options read from :mod:`mbctl.jobs.options`.

Each entry pairs a :class:`~mbctl.jobs.runner.Job` with the function that builds its parameters
from CLI-named values. The options (names, types, defaults) are read from that function's
signature, which is the one the command line calls, so ``--param model_error=5`` means exactly
what ``--model-error 5`` means.

A value given as text is parsed to the option's type: numbers, booleans (true/false, yes/no,
on/off, 1/0), ``none`` for an optional option, and text. A value with a glob character
(``*?[``) for a text or path option is expanded to the matching files (``robot=models/*.xml``).
"""

from __future__ import annotations

import glob
import inspect
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from mbctl.jobs import options as opts
from mbctl.jobs.demo import DEMO
from mbctl.jobs.demo import prepare as prepare_demo
from mbctl.jobs.g1 import G1_ARM_PD, G1_STAND, G1_TRACK, prepare_arm_pd, prepare_stand, prepare_track
from mbctl.jobs.g1_walk import G1_WALK, g1_walk_params
from mbctl.jobs.g1_walk import prepare as prepare_walk
from mbctl.jobs.g1_wbc import G1_WBC
from mbctl.jobs.g1_wbc import prepare as prepare_wbc
from mbctl.jobs.ik import IK
from mbctl.jobs.ik import prepare as prepare_ik
from mbctl.jobs.joint_step import JOINT_STEP
from mbctl.jobs.joint_step import prepare as prepare_joint_step
from mbctl.jobs.runner import Job, JobError
from mbctl.jobs.xcheck import XCHECK
from mbctl.robots.model_pair import Robot

_TRUE = ("true", "yes", "on", "1")
_FALSE = ("false", "no", "off", "0")
_NONE = ("none", "null", "")


class SweepInputError(JobError):
    """A sweep names an unknown job or option, or gives a value of the wrong type."""


class RobotSource(NamedTuple):
    """The ``load_robot`` arguments a job loads its robot from (the per-worker cache key)."""

    name: str
    scene: str | None = None
    gravity: bool | None = None
    model_dir: str | None = None


@dataclass(frozen=True)
class Option:
    """One option of a job, as the command line has it.

    Attributes:
        name: The option name with dashes as underscores (``model_error``).
        kind: The value type: bool, int, float, str or Path.
        optional: ``none`` is a valid value.
        repeatable: The CLI option may be given several times (a list); a sweep cannot vary it.
        default: The CLI default, or ``inspect.Parameter.empty`` for a required option.
    """

    name: str
    kind: type
    optional: bool
    repeatable: bool
    default: Any

    @property
    def required(self) -> bool:
        """The option has no default: a sweep must give it."""
        return self.default is inspect.Parameter.empty

    def parse(self, text: str) -> list[Any]:
        """Parse one text value to this option's type (globs expand to several).

        Raises:
            SweepInputError: The text is not a value of this type.
        """
        raw = text.strip()
        if self.optional and raw.lower() in _NONE:
            return [None]
        if self.kind is bool:
            if raw.lower() in _TRUE + _FALSE:
                return [raw.lower() in _TRUE]
            raise SweepInputError(f"{self.name}={text!r} is not a boolean; use true or false")
        if self.kind in (int, float):
            try:
                return [self.kind(raw)]
            except ValueError:
                kind = "an integer" if self.kind is int else "a number"
                raise SweepInputError(f"{self.name}={text!r} is not {kind}"
                                      + ("; or none" if self.optional else "")) from None
        if any(c in raw for c in "*?["):
            matches = sorted(glob.glob(raw))
            if not matches:
                raise SweepInputError(f"{self.name}={text!r} matches no file")
            return [self.kind(m) for m in matches]
        return [self.kind(raw)]


@dataclass(frozen=True)
class CatalogEntry:
    """A job a sweep can run.

    Attributes:
        job: The job.
        build: Builds the job's parameters from CLI-named values (in :mod:`mbctl.jobs.options`).
        main_value: The report value plotted by default.
        prepare_with_robot: The job's prepare taking an already loaded robot, or None.
        robot_source: Where the job loads its robot from, given its parameters (cache key).
    """

    job: Job[Any]
    build: Callable[..., Any]
    main_value: str
    prepare_with_robot: Callable[[Any, Robot], Any] | None = None
    robot_source: Callable[[Any], RobotSource] | None = None

    @property
    def name(self) -> str:
        """The command name."""
        return self.job.name

    @property
    def options(self) -> dict[str, Option]:
        """The job's options by name, in the command line's order."""
        hints = typing.get_type_hints(self.build)
        out: dict[str, Option] = {}
        for name, param in inspect.signature(self.build).parameters.items():
            kind, optional, repeatable = _unwrap(hints[name])
            out[name] = Option(name, kind, optional, repeatable, param.default)
        return out

    @property
    def seeded(self) -> bool:
        """The job has randomness, drawn from a ``seed`` option."""
        return "seed" in self.options

    def option(self, name: str) -> Option:
        """The option ``name``; SweepInputError naming the job's options otherwise."""
        found = self.options.get(name)
        if found is None:
            raise SweepInputError(f"{self.name} has no option {name!r}; its options are: "
                                  f"{', '.join(self.options)}")
        return found

    def params(self, values: dict[str, Any]) -> Any:
        """The job's parameters from parsed values (missing options take their defaults).

        Raises:
            SweepInputError: A required option is missing.
            ToolkitError: The parameters' own validation.
        """
        missing = [o.name for o in self.options.values() if o.required and o.name not in values]
        if missing:
            raise SweepInputError(f"{self.name} needs {', '.join(missing)}: give "
                                  + " ".join(f"--param {m}=VALUE" for m in missing))
        return self.build(**values)


def _unwrap(hint: Any) -> tuple[type, bool, bool]:
    """(type, optional, repeatable) of an annotation like ``float | None`` or ``list[str] | None``."""
    args = typing.get_args(hint)
    optional = False
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        optional = type(None) in args
        rest = [a for a in args if a is not type(None)]
        hint = rest[0]
    if typing.get_origin(hint) is list:
        return typing.get_args(hint)[0], optional, True
    return hint, optional, False


def _g1(params: Any) -> RobotSource:
    return RobotSource("g1", model_dir=params.model_dir)


def _named(params: Any) -> RobotSource:
    return RobotSource(params.robot, params.scene, model_dir=params.model_dir)


#: Every job a sweep can run, by command name.
CATALOG: dict[str, CatalogEntry] = {e.name: e for e in (
    CatalogEntry(DEMO, opts.demo, "rms_error_m", prepare_demo,
                 lambda p: RobotSource("two_link_torque", gravity=p.gravity)),
    CatalogEntry(JOINT_STEP, opts.joint_step, "error_rad", prepare_joint_step, _named),
    CatalogEntry(G1_STAND, opts.g1_stand, "pelvis_max_deviation_m", prepare_stand, _g1),
    CatalogEntry(G1_TRACK, opts.g1_track, "joint_rms_error_rad", prepare_track, _g1),
    CatalogEntry(G1_ARM_PD, opts.g1_arm_pd, "joint_rms_error_rad", prepare_arm_pd, _g1),
    CatalogEntry(G1_WBC, opts.g1_wbc, "max_foot_slip_m", prepare_wbc, _g1),
    CatalogEntry(G1_WALK, g1_walk_params, "distance_m", prepare_walk, _g1),
    CatalogEntry(XCHECK, opts.xcheck, "passed"),
    CatalogEntry(IK, opts.ik, "max_plant_residual_m", prepare_ik, _named),
)}


def entry(job: str) -> CatalogEntry:
    """The catalog entry of command ``job``; SweepInputError naming the jobs otherwise."""
    if job not in CATALOG:
        raise SweepInputError(f"unknown job {job!r}; a sweep runs one of: {', '.join(CATALOG)}")
    return CATALOG[job]


def split_values(text: str) -> list[str]:
    """``"V1,V2"`` -> the values; with a ``;`` the values are split on it (``com=0,0.1;0.05,0.1``)."""
    return text.split(";" if ";" in text else ",")


def parse_grid(job: str, params: Sequence[str], seeds: int | None = None) -> dict[str, list[Any]]:
    """The values of each swept option from ``NAME=V1,V2,...`` texts, checked against ``job``.

    Args:
        job: The command name.
        params: ``NAME=V1,V2,...`` texts (NAME as the CLI option with dashes as underscores).
        seeds: Add a ``seed`` option over 0..seeds-1 (jobs with a seed only).

    Returns:
        Option name -> its values, parsed to the option's type, in the given order.

    Raises:
        SweepInputError: Unknown job or option, a malformed or mistyped value, an option given
            twice, a repeatable option, ``seeds`` on a job without randomness, or a missing
            required option.
    """
    spec = entry(job)
    grid: dict[str, list[Any]] = {}
    for text in params:
        name, sep, values = text.partition("=")
        name = name.strip().replace("-", "_")
        if not sep or not name:
            raise SweepInputError(f"--param must look like NAME=V1,V2,... (e.g. model_error=0,5,10); "
                                  f"got {text!r}")
        option = spec.option(name)
        if option.repeatable:
            raise SweepInputError(f"{job} option {name} is repeatable (a list); a sweep cannot vary it")
        if name in grid:
            raise SweepInputError(f"--param {name} given twice; list all its values in one --param")
        grid[name] = [v for raw in split_values(values) for v in option.parse(raw)]
    if seeds is not None:
        if not spec.seeded:
            seeded = [e.name for e in CATALOG.values() if e.seeded]
            raise SweepInputError(f"{job} has no randomness (no seed option), so --seeds does not apply; "
                                  f"jobs with a seed: {', '.join(seeded)}")
        if seeds < 1:
            raise SweepInputError(f"--seeds must be >= 1; got {seeds}")
        if "seed" in grid:
            raise SweepInputError("give either --seeds N or --param seed=..., not both")
        grid["seed"] = list(range(seeds))
    missing = [o.name for o in spec.options.values() if o.required and o.name not in grid]
    if missing:
        raise SweepInputError(f"{job} needs {', '.join(missing)}: give "
                              + " ".join(f"--param {m}=VALUE" for m in missing))
    return grid


