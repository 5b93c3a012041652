"""``mbctl g1-walk course``: the waypoints' parsing and the caps on the follower's command."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from mbctl.control.exceptions import WBCSetupError
from mbctl.jobs.g1_walk_choices import WALK_DEFAULT_SPEED
from mbctl.jobs.g1_walk_course import DEFAULT_COURSE, capped, parse_waypoints, pose_of
from mbctl.jobs.g1_walk_displacement import path_length
from mbctl.planners import VelocityCommand

CAPS = VelocityCommand(0.3, 0.15, 0.3)


def test_the_caps_bound_the_command_together_on_their_ellipsoid():
    inside = np.array([0.1, 0.05, 0.1])
    np.testing.assert_array_equal(capped(inside, CAPS), inside)
    # the command that fell on the default course (0.27 m/s forward, 0.18 sideways, 0.5 rad/s turning) is
    # scaled as a whole, its direction kept, onto the ellipsoid
    out = capped(np.array([0.27, 0.18, 0.5]), CAPS)
    assert np.linalg.norm(out / np.array(CAPS)) == pytest.approx(1.0, abs=1e-12)
    direction = np.array([0.27, 0.18, 0.5]) / np.linalg.norm([0.27, 0.18, 0.5])
    np.testing.assert_allclose(out / np.linalg.norm(out), direction)
    # one axis alone reaches its cap
    np.testing.assert_allclose(capped(np.array([0.0, 0.0, -2.0]), CAPS), [0.0, 0.0, -0.3], atol=1e-15)
    assert WALK_DEFAULT_SPEED["course"] == tuple(CAPS)


def test_waypoints_parse_from_text_and_files_and_bad_ones_are_named(tmp_path):
    np.testing.assert_allclose(parse_waypoints("1,0,0;2,1,90"), [[1, 0, 0], [2, 1, math.pi / 2]])
    course = parse_waypoints(None)
    assert len(course) == len(DEFAULT_COURSE) == 12
    path = tmp_path / "course.txt"
    path.write_text("# x y yaw\n1 0 0\n2,1,90  # the turn\n")
    np.testing.assert_allclose(parse_waypoints(str(path)), [[1, 0, 0], [2, 1, math.pi / 2]])
    with pytest.raises(WBCSetupError, match=r"got the waypoint '1,2'"):
        parse_waypoints("1,2;3,4,5")
    with pytest.raises(WBCSetupError, match=r"got the waypoint '1,nan,0'$"):
        parse_waypoints("1,nan,0")
    missing = str(tmp_path / "missing.txt")  # meant as a file: the message says there is none
    with pytest.raises(WBCSetupError, match=rf"{re.escape(missing)}. \(and no file of that name\)$"):
        parse_waypoints(missing)
    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"\xff\xfe1,2,3")
    with pytest.raises(WBCSetupError, match=r"cannot read the file '.*binary.txt' \(.*codec.*a file of such"):
        parse_waypoints(str(binary))
    q = np.zeros(7)
    q[3:7] = [0, 0, math.sin(0.4), math.cos(0.4)]  # (x, y, z, w): 0.8 rad about z
    assert pose_of(q)[2] == pytest.approx(0.8, abs=1e-12)


def test_the_path_length_samples_once_a_gait_cycle_so_the_sway_cancels():
    t = np.arange(0, 10.0 + 1e-9, 0.002)
    q = np.zeros((len(t), 7))
    q[:, 0], q[:, 1] = 0.3 * t, 0.05 * np.sin(2 * math.pi * t / 1.0)  # 0.3 m/s, 5 cm sway each gait cycle
    assert path_length(t, q, 1.0) == pytest.approx(3.0, abs=1e-9)
    sway = np.linalg.norm(np.diff(q[:, :2], axis=0), axis=1).sum()
    assert sway > 3.6  # every cycle's path counts the sway (the figure the course reports is not this)
    q[:, 0] = np.where(t < 5, 0.3 * t, 1.5 - 0.3 * (t - 5))  # out and back: 3 m walked, 0 m from the start
    assert path_length(t, q, 1.0) == pytest.approx(3.0, abs=1e-9) and path_length(t[:1], q[:1], 1.0) == 0.0
