"""``g1_walk.png``'s marks: a course's waypoints (reached or not) and the pushes, where they were."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.jobs.g1_walk_plots import MARK_COLOR, draw_pushes, draw_waypoints
from mbctl.jobs.plots import new_figure


def _axes():
    return new_figure()[1][0][0]


def test_waypoints_are_numbered_with_their_yaw_a_dot_when_reached_a_cross_when_not():
    ax = _axes()
    draw_waypoints(ax, [{"x_m": 1.0, "y_m": 0.0, "yaw_deg": 90.0, "reached_at_s": 4.0},
                        {"x_m": 2.0, "y_m": 0.5, "yaw_deg": 0.0, "reached_at_s": None}])
    marks = [line for line in ax.lines if line.get_xdata().size]
    assert [(line.get_marker(), line.get_xdata()[0], line.get_ydata()[0]) for line in marks] == [
        ("o", 1.0, 0.0), ("X", 2.0, 0.5)]
    assert marks[1].get_markerfacecolor() == "w"  # the missed one hollow
    texts = [t for t in ax.texts if t.get_text()]
    assert [(t.get_text(), t.xy) for t in texts] == [("1", (1.0, 0.0)), ("2", (2.0, 0.5))]
    # the yaw arrows: 0.15 m from the waypoint along its yaw (90 deg: +y)
    heads = [t.xy for t in ax.texts if not t.get_text()]
    np.testing.assert_allclose(heads, [(1.0, 0.15), (2.15, 0.5)], atol=1e-12)
    assert [h.get_label() for h in ax.get_legend_handles_labels()[0]] == [
        "waypoint reached", "waypoint not reached"]


def test_a_push_is_an_arrow_onto_the_com_at_its_time_in_its_direction():
    ax = _axes()
    t = np.arange(0.0, 2.0, 0.002)
    c = {"time_s": t, "com_x_m": 0.3 * t, "com_y_m": np.zeros_like(t)}
    draw_pushes(ax, c, [{"time_s": 1.0, "direction_deg": 90.0, "impulse_n_s": 15.0, "survived": True},
                        {"time_s": 1.5, "direction_deg": 180.0, "impulse_n_s": 48.0, "survived": False}])
    (a, b) = ax.texts
    assert a.get_text() == "15 N s" and b.get_text() == "48 N s, fell"
    np.testing.assert_allclose(a.xy, (0.3, 0.0), atol=1e-9)  # the CoM's place at 1.0 s
    np.testing.assert_allclose(a.xyann, (0.3, -0.25), atol=1e-9)  # from below: pushed toward +y
    np.testing.assert_allclose(b.xy, (0.45, 0.0), atol=1e-9)
    np.testing.assert_allclose(b.xyann, (0.7, 0.0), atol=1e-9)  # from +x: pushed toward -x
    assert a.arrow_patch.get_edgecolor() == pytest.approx(b.arrow_patch.get_edgecolor())
    assert [line.get_color() for line in ax.lines] == [MARK_COLOR]  # one legend entry
    # on a 10 m walk's plot the arrow is 7 % of it, 0.7 m
    ax = _axes()
    draw_pushes(ax, c | {"com_x_m": 5.0 * t}, [{"time_s": 1.0, "direction_deg": 90.0, "impulse_n_s": 15.0,
                                                "survived": True}])
    np.testing.assert_allclose(ax.texts[0].xyann, (5.0, -0.7), atol=1e-3)


def test_no_waypoints_and_no_pushes_draw_nothing():
    ax = _axes()
    draw_waypoints(ax, [])
    draw_pushes(ax, {"time_s": np.zeros(1), "com_x_m": np.zeros(1), "com_y_m": np.zeros(1)}, [])
    assert not ax.lines and not ax.texts
