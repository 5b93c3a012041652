"""The DCM plan: its dynamics, continuity at phase switches, the ZMP inside the support, the feedback law."""

from __future__ import annotations

import math

import numpy as np
import pytest
import qpsolvers
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from mbctl.planners import InvalidPlanningInput
from mbctl.planners.dcm import (
    ConvexPolygon,
    DcmPlan,
    clamp_to_polygon,
    convex_hull,
    dcm_feedback,
    dcm_omega,
    polygon_margin,
)
from mbctl.planners.footsteps import Footstep, FootstepPlanner, GaitTiming, StepLimits, VelocityCommand

OMEGA = dcm_omega(0.64, 9.81)  # 3.915 rad/s
#: A G1-like sole: the contact points' rectangle (m) in the foot frame.
SOLE = np.array([[-0.05, 0.025], [-0.05, -0.025], [0.12, 0.03], [0.12, -0.03]])
CENTRE = SOLE.mean(axis=0)


def _walk(command=(0.4, 0.05, 0.2), n=6, t_ds=0.1):
    """Footsteps of a walk from both feet at rest, and the plan through them (as the walker builds it)."""
    limits = StepLimits(0.37, 0.22, 0.23, 0.237, 0.1, 0.69)
    planner = FootstepPlanner(limits, GaitTiming(0.5, t_ds), ("left", "right"))
    right = Footstep("right", -1, np.array([0.0, -0.1185, 0.0]), 0.0)
    left = Footstep("left", 1, np.array([0.0, 0.1185, 0.0]), 0.0)
    steps = [left, right, *planner.plan(right, VelocityCommand(*command), n)]
    vrps = [s.point_W([*CENTRE, 0.0])[:2] for s in steps[1:]]
    vrps.append(0.5 * (vrps[-1] + vrps[-2]))
    xi0 = 0.5 * (steps[0].position[:2] + steps[1].position[:2]) + [0.01, 0.0]
    t1 = 0.8 - 0.5 * t_ds
    switches = t1 + 0.6 * np.arange(len(vrps))  # one per VRP after xi0
    return steps, DcmPlan(OMEGA, [xi0, *vrps], switches, t_ds, 0.5, (0.0, xi0, np.zeros(2)))


def test_omega_and_bad_heights():
    assert OMEGA == pytest.approx(math.sqrt(9.81 / 0.64), rel=1e-15)
    with pytest.raises(InvalidPlanningInput, match="com_height_m"):
        dcm_omega(0.0)


def test_two_vrps_match_the_closed_form():
    # r0 = 0, r1 = 0.2, switch at 1 s, no double support, at rest on r1 after: xi(1) = 0.2 and on
    # segment 0 xi(t) = exp(omega (t - 1)) 0.2
    plan = DcmPlan(OMEGA, [[0.0, 0.0], [0.2, 0.0]], [1.0], 0.0)
    for t in (0.0, 0.5, 0.9):
        ref = plan.at(t)
        assert ref.xi[0] == pytest.approx(0.2 * math.exp(OMEGA * (t - 1.0)), rel=1e-12)
        assert ref.xi_dot[0] == pytest.approx(OMEGA * ref.xi[0], rel=1e-12)
        assert ref.vrp[0] == pytest.approx(0.0, abs=1e-15)
    after = plan.at(1.5)
    assert after.xi[0] == 0.2 and after.xi_dot[0] == 0.0 and after.vrp[0] == 0.2


def test_backward_recursion_gives_each_switchs_dcm():
    vrps = np.array([[0.0, 0.0], [0.2, 0.1], [0.4, -0.1], [0.5, 0.0]])
    t = np.array([1.0, 1.6, 2.2])
    plan = DcmPlan(OMEGA, vrps, t, 0.0)
    e = math.exp(-OMEGA * 0.6)
    xi2 = vrps[3]
    xi1 = vrps[2] + e * (xi2 - vrps[2])
    xi0 = vrps[1] + e * (xi1 - vrps[1])
    np.testing.assert_allclose(plan.xi_switch, [xi0, xi1, xi2], atol=1e-15)


def test_in_single_support_the_dcm_runs_away_from_the_stance_vrp():
    steps, plan = _walk()
    for t in np.linspace(0.9, 3.6, 40):
        ref = plan.at(t)
        np.testing.assert_allclose(ref.xi_dot, OMEGA * (ref.xi - ref.vrp), atol=1e-12)  # by definition
    # away from the double-support windows the VRP is the stance foot's sole centre
    for k, t in enumerate(0.8 + 0.6 * np.arange(5) + 0.3):
        np.testing.assert_allclose(plan.at(t).vrp, steps[k + 1].point_W([*CENTRE, 0.0])[:2], atol=1e-12)


def test_dcm_vrp_and_their_rates_are_continuous_at_every_phase_switch():
    _, plan = _walk()
    eps = 1e-9
    edges = [w for a, b in plan.windows for w in (a, b)]
    assert len(edges) == 2 * 8  # the start window and one per later switch
    for edge in edges:
        a, b = plan.at(edge - eps), plan.at(edge + eps)
        np.testing.assert_allclose(a.xi, b.xi, atol=1e-8)
        np.testing.assert_allclose(a.xi_dot, b.xi_dot, atol=1e-7)
        np.testing.assert_allclose(a.vrp, b.vrp, atol=1e-7)  # so the CMP reference does not jump


def test_the_plan_starts_at_rest_and_ends_at_rest_on_the_last_vrp():
    _, plan = _walk()
    start = plan.at(0.0)
    np.testing.assert_allclose(start.xi, plan.vrps[0], atol=1e-15)
    assert np.abs(start.xi_dot).max() < 1e-15
    end = plan.at(20.0)
    np.testing.assert_allclose(end.xi, plan.vrps[-1], atol=1e-15)
    assert np.abs(end.xi_dot).max() == 0.0


def _support(steps, plan, t):
    """The support polygon at t: both feet in a double-support window (switch j: the feet of VRPs j and
    j + 1, VRP j >= 1 being steps[j]), else the stance foot (VRP k's)."""
    feet = [steps[int(np.searchsorted(plan.switch_times_s, t, side="right"))]]
    for j, (a, b) in enumerate(plan.windows):
        if a <= t <= b:
            feet = steps[j:j + 2]
    pts = [f.point_W([*p, 0.0])[:2] for f in feet for p in SOLE]
    return convex_hull(np.array(pts))


@pytest.mark.parametrize("command", [(0.4, 0.0, 0.0), (0.0, 0.1, 0.0), (-0.2, 0.0, 0.3), (0.3, -0.05, -0.4)])
def test_the_zmp_reference_stays_inside_the_support_polygon(command):
    steps, plan = _walk(command)
    margins = [polygon_margin(plan.at(t).vrp, _support(steps, plan, t)) for t in np.arange(0.75, 4.0, 0.002)]
    # in single support the VRP is the sole centre: 25 mm from the sole's sides (the sole is 50 to 60 mm
    # wide); in double support it crosses between the feet, inside their hull
    assert min(margins) > 0.02
    assert min(margins) <= 0.0275  # the single-support centre margin is reached: the check is tight


def test_dcm_feedback_makes_the_error_decay_at_its_gain():
    # the linear inverted pendulum xddot = omega^2 (x - p) with p from the feedback law, from a 3 cm
    # DCM error: the error decays as exp(-k t)
    _, plan = _walk((0.3, 0.0, 0.0))
    k, dt = 3.0, 1e-4
    x, v = plan.at(1.0).xi + [0.03, -0.02], np.zeros(2)
    x = x - v / OMEGA
    errors = []
    for i in range(int(0.8 / dt)):
        t = 1.0 + i * dt
        ref = plan.at(t)
        p = dcm_feedback(x + v / OMEGA, ref, OMEGA, k)
        errors.append(np.linalg.norm(x + v / OMEGA - ref.xi))
        v = v + OMEGA**2 * (x - p) * dt
        x = x + v * dt
    e0 = errors[0]
    for j in (2000, 5000, 7999):
        assert errors[j] == pytest.approx(e0 * math.exp(-k * j * dt), rel=0.01)


def test_feedback_without_error_is_the_reference_vrp():
    _, plan = _walk()
    ref = plan.at(1.234)
    np.testing.assert_array_equal(dcm_feedback(ref.xi, ref, OMEGA, 3.0), ref.vrp)


def test_hull_margin_and_clamp_on_a_square():
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [1, 0.5]], dtype=float)
    hull = convex_hull(pts)
    assert len(hull) == 4
    assert polygon_margin([0.5, 0.5], hull) == pytest.approx(0.5)
    assert polygon_margin([0.9, 0.5], hull) == pytest.approx(0.1)
    assert polygon_margin([2.0, 0.5], hull) == pytest.approx(-1.0)
    assert polygon_margin([2.0, 2.0], hull) == pytest.approx(-math.sqrt(2))
    np.testing.assert_allclose(clamp_to_polygon([2.0, 0.5], hull, 0.1), [0.9, 0.5], atol=1e-9)
    np.testing.assert_allclose(clamp_to_polygon([2.0, 3.0], hull, 0.1), [0.9, 0.9], atol=1e-9)
    np.testing.assert_allclose(clamp_to_polygon([0.3, 0.4], hull, 0.1), [0.3, 0.4], atol=0)  # inside: kept
    # a margin wider than the polygon shrinks to what fits: the centre
    np.testing.assert_allclose(clamp_to_polygon([5.0, 0.5], hull, 0.7), [0.5005, 0.5], atol=1e-6)
    # a negative margin grows it (the walker's CMP beyond the soles: the hip strategy), corners sharp
    np.testing.assert_allclose(clamp_to_polygon([2.0, 0.5], hull, -0.1), [1.1, 0.5], atol=1e-9)
    np.testing.assert_allclose(clamp_to_polygon([2.0, 3.0], hull, -0.1), [1.1, 1.1], atol=1e-9)
    np.testing.assert_allclose(clamp_to_polygon([1.05, -0.05], hull, -0.1), [1.05, -0.05], atol=0)


@given(st.lists(st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2)), min_size=3, max_size=10),
       st.floats(-3.0, 3.0), st.floats(-3.0, 3.0),
       st.one_of(st.just(0.0), st.floats(1e-4, 0.05), st.floats(-0.05, -1e-4)))
@settings(max_examples=300, deadline=None)
def test_clamp_is_the_exact_projection_onto_the_shrunk_polygon(points, px, py, margin):
    hull = convex_hull(np.array(points))
    assume(len(hull) >= 3)
    polygon = ConvexPolygon(hull)
    assume(polygon.depth > 1e-4)  # not a sliver
    # nor shrunk to a sliver: within 1e-3 m of the depth the shrunk polygon is so thin that daqp's 1e-6
    # feasibility tolerance moves its answer by 5e-5 m along it (hypothesis found (0, 0), (0, 0.125),
    # (0.125, 0), (3.9e-4, -0.125) at a margin of 0.03125 m, depth 0.03135 m; the code before gave the same)
    assume(polygon.depth - min(margin, 0.999 * polygon.depth) > 1e-3)
    # nor a vertex turning by less than 1e-3 rad: the clamp accepts candidates 1e-9 m outside an edge line,
    # so near two almost parallel edges it may answer a foot 6e-11 m outside the polygon and 8e-6 m from
    # the projection (hypothesis found one: (0, 0), (0.125, 1e-6), (-0.125, 0), (0, 0.125))
    n = polygon._normals
    assume(np.all(n[:, 0] * np.roll(n, -1, axis=0)[:, 1] - n[:, 1] * np.roll(n, -1, axis=0)[:, 0] > 1e-3))
    p = np.array([px, py])
    # the projection as a QP: min |x - p|^2 subject to the shrunk polygon's half-planes
    c = polygon._offsets - min(margin, 0.999 * polygon.depth)
    x = qpsolvers.solve_qp(2.0 * np.eye(2), -2.0 * p, polygon._normals, c, solver="daqp")
    clamped = polygon.clamp(p, margin)
    # inside the shrunk polygon, and no farther from p than the QP's answer; daqp meets its constraints
    # to ~1e-6 only (e.g. (-9.5e-7, 0) for a polygon at x >= 0), so it agrees to 2e-6
    # (the clamp keeps candidates within 1e-9 (1 + max |c_i|) of an edge line: its stated tolerance)
    assert (polygon._normals @ clamped - c).max() <= 1e-9 * (1.0 + np.abs(c).max())
    assert np.linalg.norm(clamped - p) <= np.linalg.norm(x - p) + 2e-6
    np.testing.assert_allclose(clamped, x, atol=2e-6)


def test_a_point_far_outside_near_a_vertex_projects_onto_the_vertex():
    hull = convex_hull(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    # beyond a corner the projection is the shrunk polygon's corner (the old alternating projections
    # were off by more than 1e-7 m in 50 of 300 random cases of the property above)
    np.testing.assert_allclose(clamp_to_polygon([50.0, 60.0], hull, 0.1), [0.9, 0.9], atol=1e-12)


def test_plan_input_errors():
    with pytest.raises(InvalidPlanningInput, match="switch_times_s"):
        DcmPlan(OMEGA, [[0, 0], [1, 0]], [1.0, 2.0], 0.1)
    with pytest.raises(InvalidPlanningInput, match="increase"):
        DcmPlan(OMEGA, [[0, 0], [1, 0], [2, 0]], [1.0, 1.05], 0.1)
    with pytest.raises(InvalidPlanningInput, match="vrps"):
        DcmPlan(OMEGA, [[0, 0, 0]], [], 0.1)
    with pytest.raises(InvalidPlanningInput, match="initial time"):
        DcmPlan(OMEGA, [[0, 0], [1, 0]], [1.0], 0.1, initial=(2.0, [0, 0], [0, 0]))


@given(st.lists(st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2)), min_size=1, max_size=10),
       st.floats(-0.3, 0.3), st.floats(-0.3, 0.3))
@settings(max_examples=300, deadline=None)
def test_a_polygon_of_a_point_list_is_the_numpy_formulas(points, px, py):
    # of_points on a list of (x, y) pairs works on plain floats (the walker's support polygon, every cycle):
    # the same hull, normals and offsets as the array formulas, exactly; the depth and the margins (dot
    # products, which numpy's matmul rounds its own way) to 1e-15 m; margins and clamps as an array hull's
    pts = np.array(points, dtype=float)
    polygon = ConvexPolygon.of_points([list(p) for p in points])
    hull = convex_hull(pts)
    np.testing.assert_array_equal(polygon.hull, hull)
    assert set(map(tuple, hull.tolist())) <= set(map(tuple, pts.tolist()))
    p = np.array([px, py])
    if len(hull) >= 3:
        e = np.roll(hull, -1, axis=0) - hull
        with np.errstate(invalid="ignore", divide="ignore"):  # (NaN normals for an edge of ~0 length)
            normals = np.column_stack([e[:, 1], -e[:, 0]]) / np.linalg.norm(e, axis=1)[:, None]
            offsets = (hull * normals).sum(axis=1)
            depth = float((offsets - normals @ hull.mean(axis=0)).min())
            s = normals @ p - offsets
        np.testing.assert_array_equal(polygon._normals, normals)
        np.testing.assert_array_equal(polygon._offsets, offsets)
        np.testing.assert_allclose(polygon.depth, depth, rtol=0, atol=1e-15)  # (NaN for an edge of ~0 length)
        if s.max() <= -1e-15:
            assert polygon.margin(p) == pytest.approx(float(-s.max()), rel=0, abs=1e-15)
    np.testing.assert_array_equal(polygon.margin(p), ConvexPolygon(hull).margin(p))
    if len(hull) < 3 or polygon.depth > 1e-4:  # (a sliver's shrunk lines may not meet: no clamp)
        np.testing.assert_array_equal(polygon.clamp(p, 0.01), ConvexPolygon(hull).clamp(p, 0.01))


def test_polygon_of_bad_points():
    with pytest.raises(InvalidPlanningInput, match=r"finite \(n, 2\) array .*shape \(2, 2\)"):
        ConvexPolygon.of_points([[0.0, 0.0], [1.0, math.nan]])
    with pytest.raises(InvalidPlanningInput, match=r"shape \(0,\)"):
        ConvexPolygon.of_points([])


def test_a_plan_of_float_lists_is_the_plan_of_arrays():
    rng = np.random.default_rng(3)
    vrps = rng.uniform(-0.3, 0.3, (5, 2))
    switches = 0.2 + 0.5 * np.arange(4)
    initial = (0.05, rng.uniform(-0.1, 0.1, 2), rng.uniform(-0.1, 0.1, 2))
    arrays = DcmPlan(OMEGA, vrps, switches, 0.1, 0.4, initial)
    lists = DcmPlan.of_lists(OMEGA, vrps.tolist(), switches.tolist(), 0.1, 0.4, initial)
    np.testing.assert_array_equal(lists.vrps, arrays.vrps)
    np.testing.assert_array_equal(lists.switch_times_s, arrays.switch_times_s)
    for t in np.linspace(0.0, 2.5, 41):
        a, b = arrays.at(t), lists.at(t)
        np.testing.assert_array_equal(b.xi, a.xi)
        np.testing.assert_array_equal(b.vrp, a.vrp)
    with pytest.raises(InvalidPlanningInput, match="vrps must be a finite"):
        DcmPlan.of_lists(OMEGA, [[0.0, 0.0], [np.nan, 0.0]], [1.0], 0.1)
    with pytest.raises(InvalidPlanningInput, match="one per VRP after the first: 1; got 2"):
        DcmPlan.of_lists(OMEGA, [[0.0, 0.0], [1.0, 0.0]], [1.0, 2.0], 0.1)
    with pytest.raises(InvalidPlanningInput, match="increase by more than"):
        DcmPlan.of_lists(OMEGA, [[0, 0], [1, 0], [2, 0]], [1.0, 1.05], 0.1)
