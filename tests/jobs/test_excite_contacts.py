"""``mbctl excite`` reports the rows with a contact on the robot, and the torque limits it assumed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mbctl.jobs import options
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.runner import run_job

#: A planar 3-link arm started folded (its last link can swing into its first), motors without a
#: torque limit (tests/robots/assets/fold_arm.xml); ``{wall}`` is replaced by a scene geom or nothing.
FOLD = (Path(__file__).parents[1] / "robots" / "assets" / "fold_arm.xml").read_text().replace(
    "<worldbody>", "<worldbody>{wall}")
#: A post the first link sweeps through (j1 swings +-1.2 rad from 0).
POST = '<geom name="post" type="cylinder" size="0.03 0.1" pos="0.15 0.12 0"/>'


def _excite(tmp_path, wall: str):
    path = tmp_path / "fold.xml"
    path.write_text(FOLD.format(wall=wall))
    record = run_job(EXCITE, options.excite(str(path), duration=6.0), tmp_path / "run")
    assert record.exit_code == 0, record.message
    return record, record.summary().splitlines()


def test_contact_rows_are_counted_named_and_printed(tmp_path):
    record, lines = _excite(tmp_path, POST)
    rows = record.values["contact_rows"]
    logged = np.genfromtxt(tmp_path / "run" / "excite.csv", delimiter=",", names=True)["other_contacts"]
    assert rows["count"] == int(np.sum(logged > 0)) > 0  # the log's own column agrees
    assert rows["fraction"] == pytest.approx(rows["count"] / 3000)
    assert set(rows["geom_pairs"]) <= {"post/g1", "post/g2", "post/g3"} and rows["geom_pairs"]
    assert max(rows["geom_pairs"].values()) <= rows["count"]
    line = next(x for x in lines if x.startswith("contacts:"))
    assert line.startswith(f"contacts: the robot touched itself or its scene in {rows['count']} of 3000 rows "
                           f"({100 * rows['fraction']:.1f} %; rows per geom pair: post/g")


def test_the_folded_arm_never_touches_itself_and_the_assumed_limits_are_named(tmp_path):
    record, lines = _excite(tmp_path, "")
    assert record.values["contact_rows"] == {"count": 0, "fraction": 0.0, "geom_pairs": {}}
    assert not any(x.startswith("contacts:") for x in lines)
    assert ("torque limits: j1, j2, j3 have none in the model (no actuator ctrlrange or forcerange, no joint "
            "actuatorfrcrange): the design assumed 10 N m and kept its torques within 5 N m; give the "
            "actuators a ctrlrange to set them") in lines
