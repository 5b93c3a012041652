"""Size guards on a robot model, applied before the expensive steps (see :mod:`mbctl.limits`).

MuJoCo's MJCF parser takes about 30 s on a 20,000-body file and Pinocchio's ``Data`` grows as
nv^3, so a model over :data:`~mbctl.limits.MAX_BODIES` bodies is refused before it is parsed
(its bodies counted with the standard library's streaming XML reader, includes followed) and a
robot over :data:`~mbctl.limits.MAX_ROBOT_DOF` degrees of freedom before its Pinocchio model is
built.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from mbctl.limits import MAX_BODIES, MAX_ROBOT_DOF, check_limit


def count_bodies(path: Path) -> int:
    """``<body>`` elements in an MJCF file and the files it ``<include>``s (0 for a file that is not XML).

    Include paths are tried relative to the top file's folder (MuJoCo's rule), then to the
    including file's. Files that are missing or not well-formed count 0: MuJoCo reports them.
    """
    top = Path(path).resolve().parent
    seen: set[Path] = set()

    def count(file: Path) -> int:
        if file in seen or not file.is_file():
            return 0
        seen.add(file)
        n = 0
        try:
            for _, element in ET.iterparse(file, events=("start",)):
                if element.tag == "body":
                    n += 1
                elif element.tag == "include" and element.get("file"):
                    name = Path(element.get("file", ""))
                    n += count((top / name if (top / name).is_file() else file.parent / name).resolve())
        except (ET.ParseError, OSError):
            pass
        return n

    return count(Path(path).resolve())


def check_model_file_size(path: Path) -> None:
    """SizeLimitError if the MJCF at ``path`` (with its includes) has more than ``MAX_BODIES`` bodies."""
    check_limit(f"{path} with", count_bodies(path), MAX_BODIES, " bodies",
                "MuJoCo's parser alone takes ~30 s at 20,000; split the scene or simplify the model")


def check_robot_dof(nv: int, name: str) -> None:
    """SizeLimitError if the robot ``name`` has more than ``MAX_ROBOT_DOF`` degrees of freedom."""
    check_limit(f"robot {name!r} with", nv, MAX_ROBOT_DOF, " degrees of freedom",
                "Pinocchio's data grows as nv^3 (about 0.23 GB at 150, 1.7 GB at 300); take fewer trees "
                "as the robot (--root) or a smaller model")
