"""Step adaptation: the swing footstep re-planned by a small QP when the measured DCM leaves its tube.

In single support on the stance VRP r_s, the DCM follows ``xi(t) = r_s + exp(omega (t - t1)) (xi(t1) -
r_s)`` to the next switch t1. The later footsteps are placed relative to the swing footstep, so moving
it by d moves the plan's ``xi(t1)`` by d, and the plan at t by ``exp(-omega (t1 - t)) d``. A DCM error
``e = xi - xi_ref`` measured at t is therefore absorbed by the footstep moved by
``d = exp(omega (t1 - t)) e``: the plan through the moved footstep passes through the measured DCM.

The CMP feedback on the stance foot corrects errors up to what the sole allows; the **tube** is that
part, ``tube = fraction (reach - margin) / (1 + k / omega)`` per axis of the stance foot's heading
frame (reach: from the sole centre to the sole polygon's edge, forward or back and sideways, the
nearer; ``1 + k / omega`` the feedback law's factor). Only
the error outside the tube is stepped away, ``e_out = sign(e) max(|e| - tube, 0)``.

**The QP** (2 variables: the footstep's offset x = (forward, sideways) from the stance foot in its
heading frame S)::

    min_x  |x - x_des|^2 + w |x - x_nom|^2        x_des = x_nom + R_SW d,   w: nominal_weight
    s.t.   -max_backward <= x_fwd <= max_forward
           min_width(yaw) <= s x_side <= nominal_width + max_outward      (s: +1 left, -1 right)
           x inside the reach polygon: an 8-gon inscribed in the half-ellipses with semi-axes
           (max_forward or max_backward, max_outward) about the nominal stance (0, s w)

solved by the control layer's QP floor (:mod:`mbctl.control.qp`, daqp). The footstep's yaw is the
nominal one, and min_width(yaw) the narrowest stance at which its sole clears the stance sole
(:meth:`~mbctl.planners.StepLimits.min_width_for`). The result says whether the DCM left its tube
and whether a limit stopped the step from going all the way (``limited``: the robot then relies on
the next step as well).

**A quicker step** (:class:`StepTiming`, after Khadiv et al., "Walking control based on step timing
adaptation", IEEE T-RO 2020). Where a limit holds the footstep ``timing_threshold_m`` or more short
sideways (the side's reach is the shortest; a pushed step also along the heading, with
``pushed_timing_along``), the step's timing joins the QP. With the stance VRP r_s
held, the DCM at the switch is ``r_s + tau (xi_e - r_s)``, ``tau = exp(omega (t1 - t))``, ``xi_e``
the plan's DCM plus the error outside the tube; the footstep's VRP plus the plan's offset b_nom to it
(the plan's DCM at the switch less the footstep's VRP: it does not depend on t1) should equal it::

    min_(x, tau)  |r_s + tau (xi_e - r_s) - (x + c_u) - b_nom|^2 + w |x - x_nom|^2 + w_t (tau - tau_nom)^2
    s.t.          the bounds on x above,  tau_min <= tau <= tau_now

(c_u: the footstep's sole centre from its origin in S; w_t: ``timing_weight`` [m^2]; tau_nom: the
step's planned timing, tau_now the plan's now, tau_min the quickest step's). At tau = tau_now it is the
first QP; a quicker step lands before the DCM runs further, so its footstep needs less reach. The
caller re-times the swing path to match (:meth:`~mbctl.planners.swing.SwingTrajectory.retime`).

**A cross-over step** (pushed steps only, ``cross_clearance_m``). The narrowest width keeps the soles
apart sideways, so a push toward the stance side leaves the swing foot beside the stance foot, the DCM
running away past both. A footstep whose sole is ``cross_clearance_m`` ahead of the stance sole (or
behind it) clears it whatever its width: the first QP is solved again with ``x_fwd >= l + c`` (``l`` the
sole's length; or ``x_fwd <= -(l + c)``) and no narrowest width, within the same reach polygon, and the
crossing footstep is taken when it lands ``cross_gain_m`` or more nearer the QP's optimum than the
uncrossed one (without timing adaptation: the swing keeps its timing).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.qp import QPData, QPSolver
from mbctl.planners.dcm import convex_hull
from mbctl.planners.footsteps import Footstep, FootstepPlanner

#: Vertices of the reach polygon [-].
REACH_VERTICES = 8
#: Which shortfalls along the heading make a pushed step quicker (``StepAdapter``'s ``pushed_timing_along``).
TIMING_ALONG = ("none", "backward", "both")
#: A quicker step still short of the DCM's need by more than this [m] counts as ``limited``.
SHORT_M = 0.005


class StepTiming(NamedTuple):
    """The swing's timing for :meth:`StepAdapter.adapt` to adapt (times from now to the DCM plan's switch).

    Attributes:
        dcm_ref_W: The plan's DCM now (2,) [m] in W.
        nominal_s: The time to the switch the step was planned with [s] (the longest allowed).
        min_s: The time to the switch of the quickest step allowed [s].
    """

    dcm_ref_W: np.ndarray
    nominal_s: float
    min_s: float


class StepAdaptation(NamedTuple):
    """One adaptation of the swing footstep.

    Attributes:
        footstep: The footstep to swing to.
        shift_m: Its shift from the nominal footstep (2,) [m] in W.
        outside_tube: The measured DCM was outside its tube (else the nominal footstep is kept).
        limited: A step limit stopped the footstep short of where the DCM needed it.
        solve_time_s: The QP's solve time [s] (0 when the DCM was inside its tube).
        time_to_switch_s: The adapted time from now to the switch [s] (None: the timing was not adapted).
    """

    footstep: Footstep
    shift_m: np.ndarray
    outside_tube: bool
    limited: bool
    solve_time_s: float
    time_to_switch_s: float | None = None


def dcm_tube(sole_points_F: npt.ArrayLike, margin_m: float, gain_1_s: float, omega_rad_s: float,
             fraction: float) -> np.ndarray:
    """Half-widths (forward, sideways) [m] of the DCM tube (see the module docstring).

    Args:
        sole_points_F: The sole's contact points (n, 3) [m] in the foot frame.
        margin_m: The CMP's margin inside the sole [m].
        gain_1_s: The DCM feedback gain k [1/s].
        omega_rad_s: ``sqrt(g / z_c)`` [rad/s].
        fraction: The share of the correctable error kept in the tube, in [0, 1].
    """
    pts = np.asarray(sole_points_F, dtype=float)[:, :2]
    centre = pts.mean(axis=0)
    hull = convex_hull(pts)
    a, b = hull, np.roll(hull, -1, axis=0)
    normal = np.column_stack([(b - a)[:, 1], -(b - a)[:, 0]])  # outward (counter-clockwise hull)
    depth = (normal * (a - centre)).sum(axis=1)  # n . (a - c) > 0: the centre is inside
    reach = np.empty(2)
    for axis in range(2):  # the nearest edge along +axis and -axis
        along = normal[:, axis]
        reach[axis] = min(float(np.min(depth[along > 0] / along[along > 0])),
                          float(np.min(depth[along < 0] / -along[along < 0])))
    return fraction * np.maximum(reach - margin_m, 0.0) / (1.0 + gain_1_s / omega_rad_s)


class StepAdapter:
    """The step-adaptation QP of one walker (see the module docstring).

    Args:
        planner: The footstep planner (its limits bound the QP).
        omega_rad_s: ``sqrt(g / z_c)`` [rad/s].
        tube_m: The DCM tube's half-widths (forward, sideways) [m].
        nominal_weight: w [-] (> 0): how much the footstep prefers the nominal one.
        sole_centre_xy: The sole centre (x, y) [m] in the foot frame (a footstep's VRP).
        timing_weight: w_t [m^2] (> 0): how much the step's timing prefers the planned one.
        timing_threshold_m: The timing is adapted once a limit holds the footstep this far [m] short
            sideways (the side's reach is the shortest; walking sideways at the limit, small DCM errors
            are left to the next step).
        pushed_outward_m: The outward limit [m] beyond the nominal width for a step :meth:`adapt` is
            told is pushed (None: the planner's ``max_outward_m``, as for the others).
        cross_clearance_m: A pushed step toward the stance side may cross in front of or behind the
            stance foot, its sole this far [m] clear of the stance sole along the heading (None or
            ``inf``: never; needs the planner's ``sole_xy_m``).
        cross_gain_m: ... when the crossing footstep lands this much [m] nearer the optimum.
        pushed_forward_m: The forward limit [m] for a pushed step (None: the planner's ``max_forward_m``).
        pushed_backward_m: The backward limit [m] for a pushed step (None: the planner's
            ``max_backward_m``).
        pushed_timing_along: A pushed step held ``timing_threshold_m`` or more short along the heading is
            made quicker too: ``"none"`` (only a sideways shortfall adapts the timing), ``"backward"``
            (a footstep held short of a backward optimum) or ``"both"``.
        cross_quick: A crossing footstep's swing takes the quickest timing :meth:`adapt`'s ``timing``
            allows (its ``min_s``), where it otherwise keeps the plan's.

    Raises:
        WBCSetupError: A non-positive omega or weight, or a tube that is not 2 finite values >= 0.
    """

    def __init__(self, planner: FootstepPlanner, omega_rad_s: float, tube_m: npt.ArrayLike,
                 nominal_weight: float = 0.01, sole_centre_xy: tuple[float, float] = (0.0, 0.0),
                 timing_weight: float = 0.001, timing_threshold_m: float = 0.05,
                 pushed_outward_m: float | None = None, cross_clearance_m: float | None = None,
                 cross_gain_m: float = 0.05, pushed_forward_m: float | None = None,
                 pushed_backward_m: float | None = None, pushed_timing_along: str = "none",
                 cross_quick: bool = False):
        tube = np.asarray(tube_m, dtype=float)
        if not (omega_rad_s > 0 and nominal_weight > 0 and timing_weight > 0 and tube.shape == (2,)
                and np.all(np.isfinite(tube)) and np.all(tube >= 0)):
            raise WBCSetupError(f"step adaptation needs omega > 0, nominal_weight > 0, timing_weight > 0 "
                                f"and a tube of 2 values >= 0; got {omega_rad_s!r}, {nominal_weight!r}, "
                                f"{timing_weight!r}, {tube_m!r}")
        self.planner, self.omega, self.tube_m = planner, float(omega_rad_s), tube
        self.nominal_weight, self.timing_weight = nominal_weight, float(timing_weight)
        self.timing_threshold_m = float(timing_threshold_m)
        self.sole_centre_xy = (float(sole_centre_xy[0]), float(sole_centre_xy[1]))
        self._solver = QPSolver(2)
        self._timed_solver = QPSolver(3)
        self._h = 2.0 * (1.0 + nominal_weight)  # H = h I
        self._H = self._h * np.eye(2)
        lim = planner.limits
        angles = 2.0 * math.pi * np.arange(REACH_VERTICES) / REACH_VERTICES
        self._unit = np.column_stack([np.cos(angles), np.sin(angles)])
        out = lim.max_outward_m if pushed_outward_m is None else float(pushed_outward_m)
        fwd = lim.max_forward_m if pushed_forward_m is None else float(pushed_forward_m)
        back = lim.max_backward_m if pushed_backward_m is None else float(pushed_backward_m)
        if not all(math.isfinite(v) and v > 0 for v in (out, fwd, back)):
            raise WBCSetupError(f"pushed_outward_m, pushed_forward_m and pushed_backward_m must be finite "
                                f"and > 0 [m]; got {pushed_outward_m!r}, {pushed_forward_m!r}, "
                                f"{pushed_backward_m!r}")
        self._outward = {False: lim.max_outward_m, True: out}
        #: (forward, backward) limits [m] of a walking step (False) and a pushed one (True).
        self._along = {False: (lim.max_forward_m, lim.max_backward_m), True: (fwd, back)}
        if pushed_timing_along not in TIMING_ALONG:
            raise WBCSetupError(f"pushed_timing_along must be one of {', '.join(TIMING_ALONG)}; got "
                                f"{pushed_timing_along!r}")
        self.pushed_timing_along = pushed_timing_along
        if not (cross_clearance_m is None or cross_clearance_m >= 0) or not (math.isfinite(cross_gain_m)
                                                                             and cross_gain_m >= 0):
            raise WBCSetupError(f"cross_clearance_m must be >= 0 [m] (inf or None: no cross-over) and "
                                f"cross_gain_m finite and >= 0 [m]; got {cross_clearance_m!r}, "
                                f"{cross_gain_m!r}")
        xs = [x for x, _ in lim.sole_xy_m]
        #: A crossing footstep's least offset along the stance heading [m] (None: no cross-over steps).
        self.cross_ahead_m = (max(xs) - min(xs) + cross_clearance_m if xs and cross_clearance_m is not None
                              and math.isfinite(cross_clearance_m) else None)
        self.cross_gain_m = float(cross_gain_m)
        #: A crossing footstep's swing takes the quickest timing ``timing`` allows.
        self.cross_quick = bool(cross_quick)
        self._reach: dict[tuple[int, bool], tuple[np.ndarray, np.ndarray]] = {}

    def _reach_rows(self, side: int, pushed: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The reach polygon ``G x <= h`` about the nominal stance (0, side w), for a step on ``side``.

        Made once per side and outward limit (the limits are the planner's, fixed).
        """
        rows = self._reach.get((side, pushed))
        if rows is None:
            rows = self._reach[(side, pushed)] = self._reach_polygon(side, self._outward[pushed],
                                                                     *self._along[pushed])
        return rows

    def _reach_polygon(self, side: int, out: float, fwd: float, back: float) -> tuple[np.ndarray, np.ndarray]:
        w = self.planner.limits.nominal_width_m
        u = self._unit
        vertices = np.column_stack([np.where(u[:, 0] >= 0, fwd, back) * u[:, 0], out * u[:, 1] + side * w])
        nxt = np.roll(vertices, -1, axis=0)
        edge = nxt - vertices
        normal = np.column_stack([edge[:, 1], -edge[:, 0]])  # outward for counter-clockwise vertices
        return normal, (normal * vertices).sum(axis=1)

    def adapt(self, stance: Footstep, nominal: Footstep, dcm_error_W: npt.ArrayLike,
              time_to_switch_s: float,
              timing: StepTiming | Callable[[], StepTiming | None] | None = None,
              pushed: bool = False) -> StepAdaptation:
        """The swing footstep for a DCM error measured ``time_to_switch_s`` [s] before the next switch.

        Args:
            stance: The stance footstep.
            nominal: The command's footstep for the swing foot.
            dcm_error_W: ``xi - xi_ref`` (2,) [m] in W, the reference being the plan through ``nominal``.
            time_to_switch_s: ``t1 - t`` [s] (>= 0) in the plan.
            timing: Adapt the step's timing too, within these (None: the plan's timing stays), or a
                function giving them, called only when a limit holds the footstep short (most cycles
                need no timing: the DCM is in its tube).
            pushed: The step recovers from a push: its outward limit is ``pushed_outward_m``.
        """
        c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        e = np.asarray(dcm_error_W, dtype=float)
        ex, ey = e[:2].tolist()
        fwd, side = c * ex + s * ey, -s * ex + c * ey
        tube_fwd, tube_side = self.tube_m.tolist()
        if abs(fwd) - tube_fwd <= 0.0 and abs(side) - tube_side <= 0.0:  # in the tube (most cycles)
            return StepAdaptation(nominal, np.zeros(2), False, False, 0.0)
        # on plain floats from here too (the same operations as numpy's elementwise ones)
        out = [(1.0 if v > 0 else -1.0 if v < 0 else 0.0) * max(abs(v) - tube, 0.0)  # np.sign: 0 at 0
               for v, tube in ((fwd, tube_fwd), (side, tube_side))]
        if out[0] == 0.0 and out[1] == 0.0:
            return StepAdaptation(nominal, np.zeros(2), False, False, 0.0)
        (nx, ny, _), (sx, sy, _) = nominal.position.tolist(), stance.position.tolist()
        dx, dy = nx - sx, ny - sy
        x_nom = [c * dx + s * dy, -s * dx + c * dy]
        gain = math.exp(self.omega * max(time_to_switch_s, 0.0))
        x_des = [x_nom[0] + gain * out[0], x_nom[1] + gain * out[1]]
        lim, side = self.planner.limits, nominal.side
        dyaw = math.remainder(nominal.yaw_rad - stance.yaw_rad, 2.0 * math.pi)
        widths = (lim.min_width_for(dyaw, side) * side, (lim.nominal_width_m + self._outward[pushed]) * side)
        fwd_m, back_m = self._along[pushed]
        lb = np.array([-back_m, min(widths)])
        ub = np.array([fwd_m, max(widths)])
        G, h = self._reach_rows(side, pushed)
        w = self.nominal_weight
        optimum = [(x_des[0] + w * x_nom[0]) / (1.0 + w), (x_des[1] + w * x_nom[1]) / (1.0 + w)]  # H x* = -c
        t0 = time.perf_counter()
        result = self._solver.solve(QPData(self._H, np.array([-self._h * optimum[0], -self._h * optimum[1]]),
                                           lb, ub, G, h))
        solve_time = time.perf_counter() - t0
        x = result.x.tolist() if result.x is not None else x_nom  # (never None: (0, s w) is feasible)
        limited = max(abs(x[0] - optimum[0]), abs(x[1] - optimum[1])) > 1e-9
        short = abs(x[1] - optimum[1])
        if pushed and self.pushed_timing_along != "none":  # backward: the footstep ahead of its optimum
            along = x[0] - optimum[0] if self.pushed_timing_along == "backward" else abs(x[0] - optimum[0])
            short = max(short, along)
        held = timing is not None and short > self.timing_threshold_m
        given = (timing() if callable(timing) else timing) if held else None
        if given is not None and given.min_s < time_to_switch_s - 1e-6:
            # held short: the quicker step's QP (at the plan's timing it is the same QP, so it does no worse)
            timed = self._adapt_timed(stance, nominal, given, (c, s), x_nom, out, time_to_switch_s, lb, ub,
                                      (G, h))
            adapted = timed._replace(solve_time_s=timed.solve_time_s + solve_time)
        else:
            adapted = _placed(stance, nominal, (c, s), x, limited, solve_time)
        if pushed and adapted.limited and self.cross_ahead_m is not None and out[1] * side < 0.0:  # inward
            crossed = self._cross_over(adapted, stance, nominal, optimum, (G, h))
            if self.cross_quick and crossed.footstep is not adapted.footstep and timing is not None:
                if given is None:
                    given = timing() if callable(timing) else timing
                if given is not None and given.min_s < time_to_switch_s - 1e-6:
                    return crossed._replace(time_to_switch_s=given.min_s)
            return crossed
        return adapted

    def _cross_over(self, result: StepAdaptation, stance: Footstep, nominal: Footstep, optimum: list[float],
                    reach: tuple[np.ndarray, np.ndarray]) -> StepAdaptation:
        """``result``, or the crossing footstep if it lands ``cross_gain_m`` nearer ``optimum`` (in S)."""
        c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        sx, sy, _ = stance.position.tolist()
        px, py, _ = result.footstep.position.tolist()
        kept = [c * (px - sx) + s * (py - sy), -s * (px - sx) + c * (py - sy)]
        best = max(math.hypot(kept[0] - optimum[0], kept[1] - optimum[1]) - self.cross_gain_m, 0.0)
        lim, ahead = self.planner.limits, float(self.cross_ahead_m or 0.0)
        widest = lim.nominal_width_m + self._outward[True]
        fwd_m, back_m = self._along[True]
        q = np.array([-self._h * optimum[0], -self._h * optimum[1]])
        crossed, t0 = None, time.perf_counter()
        for low, high in ((ahead, fwd_m), (-back_m, -ahead)):  # ahead, behind
            if low <= high:
                x = self._solver.solve(QPData(self._H, q, np.array([low, -widest]), np.array([high, widest]),
                                              *reach)).x
                if x is not None and math.hypot(x[0] - optimum[0], x[1] - optimum[1]) < best:
                    crossed, best = x.tolist(), math.hypot(x[0] - optimum[0], x[1] - optimum[1])
        solve_time = result.solve_time_s + time.perf_counter() - t0
        if crossed is None:
            return result._replace(solve_time_s=solve_time)
        limited = max(abs(crossed[0] - optimum[0]), abs(crossed[1] - optimum[1])) > 1e-9
        return _placed(stance, nominal, (c, s), crossed, limited, solve_time)

    def _adapt_timed(self, stance: Footstep, nominal: Footstep, timing: StepTiming, cs: tuple[float, float],
                     x_nom: list[float], out: list[float], time_to_switch_s: float, lb: np.ndarray,
                     ub: np.ndarray, reach: tuple[np.ndarray, np.ndarray]) -> StepAdaptation:
        """:meth:`adapt` with the step's timing (the module docstring's second QP), in S about the stance."""
        c, s = cs
        sx, sy, _ = stance.position.tolist()
        rx, ry = timing.dcm_ref_W.tolist()
        xi_ref = np.array([c * (rx - sx) + s * (ry - sy), -s * (rx - sx) + c * (ry - sy)])
        r_s = np.array(self.sole_centre_xy)
        dyaw = nominal.yaw_rad - stance.yaw_rad
        cu, su = math.cos(dyaw), math.sin(dyaw)
        c_u = np.array([cu * r_s[0] - su * r_s[1], su * r_s[0] + cu * r_s[1]])
        x0 = np.array(x_nom)
        omega = self.omega
        b_nom = r_s + math.exp(omega * max(time_to_switch_s, 0.0)) * (xi_ref - r_s) - x0 - c_u
        a = xi_ref + np.array(out) - r_s
        k = r_s - c_u - b_nom
        w, w_t = self.nominal_weight, self.timing_weight
        tau_nom = math.exp(omega * max(timing.nominal_s, 0.0))
        tau_min = math.exp(omega * max(timing.min_s, 0.0))
        tau_max = math.exp(omega * max(time_to_switch_s, 0.0))  # quicker only
        H = np.zeros((3, 3))
        H[:2, :2] = 2.0 * (1.0 + w) * np.eye(2)
        H[:2, 2] = H[2, :2] = -2.0 * a
        H[2, 2] = 2.0 * (float(a @ a) + w_t)
        q = np.concatenate([-2.0 * k - 2.0 * w * x0, [2.0 * float(a @ k) - 2.0 * w_t * tau_nom]])
        G, h = reach
        t0 = time.perf_counter()
        result = self._timed_solver.solve(QPData(H, q, np.append(lb, tau_min), np.append(ub, tau_max),
                                                 np.column_stack([G, np.zeros(len(G))]), h))
        solve_time = time.perf_counter() - t0
        if result.x is None:  # (never: the nominal step at its timing is feasible)
            return StepAdaptation(nominal, np.zeros(2), True, True, solve_time)
        x = result.x
        short = float(np.linalg.norm(x[2] * a - x[:2] + k))  # the DCM's offset from b_nom at the switch
        return _placed(stance, nominal, cs, x[:2].tolist(), short > SHORT_M, solve_time,
                       math.log(max(float(x[2]), 1.0)) / omega)


def _placed(stance: Footstep, nominal: Footstep, cs: tuple[float, float], x: list[float], limited: bool,
            solve_time_s: float, time_to_switch_s: float | None = None) -> StepAdaptation:
    """The adapted footstep at ``x`` (2,) [m] in S, the stance foot's frame about its position.

    ``cs``: the cosine and sine of the stance foot's yaw.
    """
    c, s = cs
    (sx, sy, _), (nx, ny, nz) = stance.position.tolist(), nominal.position.tolist()
    px, py = sx + (c * x[0] - s * x[1]), sy + (s * x[0] + c * x[1])
    return StepAdaptation(nominal._replace(position=np.array([px, py, nz])), np.array([px - nx, py - ny]),
                          True, limited, solve_time_s, time_to_switch_s)
