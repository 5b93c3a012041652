"""The excitation's balance watch: the support polygon's margins, a CoP from wrenches, scaling, stopping."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.jobs import excite_g1_balance as bal
from mbctl.jobs.excite_g1_balance import (
    Balance,
    BalanceWatch,
    SupportPolygon,
    convex_hull_2d,
    measured_cop_W,
    signed_distance,
)
from mbctl.robots.g1 import FEET, FOOT_BODIES, crouched_start


def test_the_hull_is_counter_clockwise_and_the_distance_signed():
    square = [(0, 0), (1, 0), (1, 1), (0, 1), (0.5, 0.5), (0.5, 0.0)]  # an inner and an edge point
    hull = convex_hull_2d(square)
    assert len(hull) == 4
    a, b = hull[1] - hull[0], hull[2] - hull[1]
    assert a[0] * b[1] - a[1] * b[0] > 0  # turns left: counter-clockwise
    assert signed_distance(hull, (0.5, 0.5)) == pytest.approx(0.5)
    assert signed_distance(hull, (0.9, 0.5)) == pytest.approx(0.1)
    assert signed_distance(hull, (1.2, 0.5)) == pytest.approx(-0.2)  # beside an edge: exact
    assert signed_distance(convex_hull_2d([(0, 0), (1, 0)]), (0.5, 0.0)) == -np.inf  # a segment has no inside


def test_the_cop_of_foot_wrenches_is_where_the_point_forces_act():
    rng = np.random.default_rng(2)
    points = np.column_stack([rng.uniform(-0.1, 0.1, (6, 2)), np.full(6, 0.02)])  # on the plane z = 0.02
    forces = np.column_stack([rng.uniform(-5, 5, (6, 2)), rng.uniform(10, 100, 6)])
    origins = np.array([[0.0, 0.1, 0.06], [0.02, -0.1, 0.07]])
    wrenches = np.zeros((2, 6))
    for k, (p, f) in enumerate(zip(points, forces, strict=True)):  # three points per body
        body = k // 3
        wrenches[body, :3] += f
        wrenches[body, 3:] += np.cross(p - origins[body], f)
    expected = forces[:, 2] @ points[:, :2] / forces[:, 2].sum()
    cop = measured_cop_W(wrenches, origins, 0.02)
    np.testing.assert_allclose(cop[:2], expected, atol=1e-12)
    assert measured_cop_W(np.zeros((2, 6)), origins, 0.0) is None


def test_the_g1_standing_still_has_its_capture_point_inside_both_soles(g1_torque):
    model = g1_torque.pin_model
    from mbctl.control.wbc.contacts import foot_contact_from_model

    soles = {f: foot_contact_from_model(g1_torque, f).points_F for f in FEET}
    polygon = SupportPolygon(model, soles, dict(zip(FEET, FOOT_BODIES, strict=True)))
    com, vcom = polygon.update(crouched_start(g1_torque), np.zeros(model.nv))
    both = polygon.margins(0.0, com, vcom, FEET, None)
    one = polygon.margins(0.0, com, vcom, FEET[:1], None)
    # the soles reach 5 cm behind the feet's frames and 12 cm ahead: the CoM is 6 cm from the back edge
    assert 0.05 < both.com_margin_m < 0.07 and np.isnan(both.cop_margin_m)
    assert one.com_margin_m < -0.09  # over one sole the CoM is far outside it
    moving = polygon.margins(0.0, com, np.array([-0.3, 0.0, 0.0]), FEET, None)  # toward the back edge
    assert moving.com_margin_m < both.com_margin_m - 0.07  # 0.3 m/s over omega (~3.9 1/s) is 7.7 cm


def _at(t: float, margin: float) -> Balance:
    return Balance(t, FEET, margin, margin + 0.01)


def test_the_watch_scales_then_stops_and_reports_when_and_why():
    watch = BalanceWatch()
    watch.observe(_at(0.0, 0.05))
    assert watch.scale_at(0.0) == (1.0, 0.0, 0.0) and watch.section()["balance_scaled_at_s"] is None
    watch.observe(_at(1.0, bal.SCALE_MARGIN_M - 1e-3))
    watch.observe(_at(1.2, bal.SCALE_MARGIN_M - 1e-3))  # within the hold time: no second scaling
    assert [s[:2] for s in watch.scalings] == [(1.0, bal.SCALE_FACTOR)]
    s, ds, _ = watch.scale_at(1.0 + bal.SCALE_RAMP_S / 2)
    assert s == pytest.approx(0.5 * (1.0 + bal.SCALE_FACTOR)) and ds < 0  # a smooth step down
    assert watch.scale_at(1.0 + bal.SCALE_RAMP_S)[0] == pytest.approx(bal.SCALE_FACTOR)
    watch.observe(_at(3.0, bal.STOP_MARGIN_M - 1e-3))
    assert watch.stopped_at_s == 3.0 and "CoM 1.0 mm from the edge" in watch.stop_reason
    assert watch.scale_at(3.0)[0] == pytest.approx(bal.SCALE_FACTOR)
    assert watch.scale_at(3.0 + bal.SCALE_RAMP_S) == (0.0, 0.0, 0.0)
    watch.observe(_at(4.0, -0.5))  # after the stop only the record changes
    section = watch.section()
    assert section["balance_scaled_at_s"] == 1.0 and section["balance_stopped_at_s"] == 3.0
    assert section["min_balance_margin_m"] == -0.5 and section["min_balance_margin_at_s"] == 4.0


def test_the_watch_stops_instead_of_scaling_below_the_smallest_scale():
    watch = BalanceWatch()
    t = 0.0
    while watch.stopped_at_s is None:
        watch.observe(_at(t, bal.SCALE_MARGIN_M - 1e-3))
        t += bal.SCALE_HOLD_S
    assert len(watch.scalings) == int(np.log(bal.MIN_SCALE) / np.log(bal.SCALE_FACTOR))
    assert watch.scalings[-1][1] >= bal.MIN_SCALE
