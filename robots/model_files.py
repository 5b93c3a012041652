"""Where a robot's two models come from, and reading them: MJCF or URDF files, MjSpecs.

Every failure to read or compile a model raises :class:`~mbctl.robots.exceptions.ModelFileError`
naming the file.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import pinocchio as pin

from mbctl.robots.exceptions import ModelFileError


@dataclass(frozen=True)
class ModelSource:
    """Where a robot's two models come from, for reports and hashing.

    Attributes:
        name: Robot name (a known robot) or the robot file's stem.
        robot_file: The robot's file (MJCF or URDF); Pinocchio's parser reads it when
            ``analytic`` is "parser".
        scene_file: MJCF file MuJoCo reads (may include ``robot_file``).
        origin: Human-readable provenance (e.g. "embedded", "menagerie unitree_g1 @ <dir>").
        edits: Load-time edits applied on top of the files (MjSpec or Pinocchio), in order.
        analytic: How the Pinocchio model was built: "mujoco" (from MuJoCo's compiled model,
            ``robots.pin_from_mj``; the default) or "parser" (Pinocchio's own parser reading
            ``robot_file``: the independent path, e.g. a URDF checked against its MJCF).
        roots: Bodies whose trees are the robot (empty: the trees the actuators drive; see
            ``robots/scene.py``).
    """

    name: str
    robot_file: Path
    scene_file: Path
    origin: str
    edits: tuple[str, ...] = field(default=())
    analytic: str = "parser"
    roots: tuple[str, ...] = field(default=())

    def files(self) -> dict[str, Path]:
        """The model files by role (deduplicated)."""
        out = {"robot": self.robot_file}
        if self.scene_file != self.robot_file:
            out["scene"] = self.scene_file
        return out


def load_mj_spec(path: Path) -> mujoco.MjSpec:
    """Parse an MJCF file into an MjSpec; a bad file raises ModelFileError naming it."""
    if not path.is_file():
        raise ModelFileError(f"Model file {str(path)!r} does not exist.")
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise ModelFileError(f"MuJoCo cannot parse {str(path)!r}: {exc}") from exc


def compile_spec(spec: mujoco.MjSpec, path: Path) -> mujoco.MjModel:
    """Compile an MjSpec; a failure raises ModelFileError naming the file."""
    try:
        return spec.compile()
    except ValueError as exc:
        raise ModelFileError(f"MuJoCo cannot compile {str(path)!r}: {exc}") from exc


def load_pin_model(path: Path) -> pin.Model:
    """Build a Pinocchio model from an MJCF (or URDF, by suffix) file; errors name the file."""
    if not path.is_file():
        raise ModelFileError(f"Model file {str(path)!r} does not exist.")
    try:
        if path.suffix.lower() == ".urdf":
            return pin.buildModelFromUrdf(str(path))
        return pin.buildModelFromMJCF(str(path))
    except (ValueError, RuntimeError, IndexError) as exc:
        raise ModelFileError(f"Pinocchio cannot parse {str(path)!r}: {exc}") from exc


def pin_model_from_spec(spec: mujoco.MjSpec) -> pin.Model:
    """Build a Pinocchio model from an (edited) MjSpec via its XML.

    Pinocchio has no MjSpec reader, so the spec is written to a temporary MJCF next to nothing:
    mesh files are irrelevant to Pinocchio's dynamics (inertias are explicit in ``<inertial>``).
    """
    xml = spec.to_xml()
    with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=True) as tmp:
        tmp.write(xml)
        tmp.flush()
        return pin.buildModelFromMJCF(tmp.name)
