"""The excitation's balance watch: how far the G1 is from tipping, and what the excitation does about it.

**The margin.** The support polygon is the convex hull, on the floor, of the sole points
(:class:`~mbctl.control.wbc.contacts.FootContact`) of the feet that carry the robot; the balance
margin is the signed distance [m] (positive inside) of the worse of two points to its edge:

* the CoM's ground projection moved by its velocity: the capture point ``c + c_dot / omega``
  with ``omega = sqrt(g / h)``, h the CoM's height over the soles (a CoM moving toward an edge
  counts as closer to it, one moving inward as farther; at rest it is the CoM),
* the centre of pressure of every contact force together.

Where they come from depends on the plant: in-process the feet that carry (at least
:data:`SUPPORT_FORCE_N`) and the CoP come from the contact wrenches MuJoCo applied
(:class:`~mbctl.sim.monitor.PlantMonitor`); over DDS nothing measures the feet, so both come from
the whole-body QP's solution (its contacts with weight, its predicted point forces) and the CoM from
the estimated state. The QP keeps its CoP inside the soles by construction, so over DDS the CoP
margin says how close the controller's plan is to the sole's edge, not where the robot's CoP is.

**The watch** (:class:`BalanceWatch`). When the margin falls below :data:`SCALE_MARGIN_M` the
excitation's amplitude is scaled down by :data:`SCALE_FACTOR` (at most once per
:data:`SCALE_HOLD_S`); below :data:`STOP_MARGIN_M`, or once the scale would fall under
:data:`MIN_SCALE`, the excitation stops into a stance: every motion ramps out over
:data:`SCALE_RAMP_S`, no step begins and the one under way is cut short (its foot put down,
:mod:`mbctl.jobs.excite_g1_steps`), and the controller holds the stance to the end of the run
(a stop does not end the run early: on a robot, the loop's end is the damping command).

The thresholds, from measured runs: the payload excitation (``--payload
2.0@torso_link:0.05,0,0.25``, 30 s) keeps at least 13.3 mm, the nominal one 13.8 mm; before the
swing legs were fixed, the payload excitation went under 2 mm at t = 18.71 s (a foot rolling on
its edge as it was released) and fell at 25.62 s, and the 16 s one went under 2 mm at 7.20 s,
0.65 s before its QP had no solution. With 8 kg hidden on the left elbow the margin goes under
2 mm as the first foot is released (t = 3.30 s): the step is cut short and the G1 stands to the
end; without the watch its QP has no solution at 4.29 s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

#: Gravity [m/s^2] of the capture point's pendulum.
GRAVITY_M_S2 = 9.81
#: A foot carries the robot (its sole is in the support polygon) with at least this normal force [N].
SUPPORT_FORCE_N = 2.0
#: Margin [m] under which the excitation's amplitude is scaled down.
SCALE_MARGIN_M = 0.006
#: Margin [m] under which the excitation stops into a stance.
STOP_MARGIN_M = 0.002
#: Each scaling multiplies the amplitude by this [-]; a scale under :data:`MIN_SCALE` stops instead.
SCALE_FACTOR = 0.7
MIN_SCALE = 0.3
#: After a scaling the watch waits this long [s] before scaling again (the smaller motion takes over).
SCALE_HOLD_S = 0.5
#: How long [s] the amplitude takes to reach a new scale (smooth step), and to ramp out on a stop.
SCALE_RAMP_S = 1.0


def convex_hull_2d(points: npt.ArrayLike) -> np.ndarray:
    """The convex hull (h, 2) of 2-D points, counter-clockwise, by Andrew's monotone chain."""
    pts = sorted({(float(x), float(y)) for x, y in np.asarray(points, dtype=float)[:, :2]})
    if len(pts) < 3:
        return np.array(pts)

    def half(seq: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def signed_distance(hull: np.ndarray, point: npt.ArrayLike) -> float:
    """Distance [m] of ``point`` (2,) to the edge of the counter-clockwise convex ``hull``; > 0 inside.

    Outside it is the largest distance beyond an edge's line (a lower bound of the Euclidean
    distance, exact beside an edge); a hull of fewer than 3 points has no inside (-inf).
    """
    if len(hull) < 3:
        return -np.inf
    p = np.asarray(point, dtype=float)[:2]
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.column_stack([-edges[:, 1], edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
    return float(np.min(np.sum((p - hull) * normals, axis=1)))


@dataclass(frozen=True)
class Balance:
    """The balance of one cycle.

    Attributes:
        time_s: The state's time [s].
        feet: The feet in the support polygon.
        com_margin_m: The CoM's capture point's distance to the polygon's edge [m] (> 0 inside).
        cop_margin_m: The CoP's distance to the edge [m] (NaN without a normal force).
    """

    time_s: float
    feet: tuple[str, ...]
    com_margin_m: float
    cop_margin_m: float

    @property
    def margin_m(self) -> float:
        """The worse of the two [m] (the CoM's when there is no CoP)."""
        return self.com_margin_m if np.isnan(self.cop_margin_m) else min(self.com_margin_m, self.cop_margin_m)


class SupportPolygon:
    """The feet's soles in W from a configuration, and the margins of the CoM and a CoP against their hull.

    Args:
        model: The controller's Pinocchio model (floating base).
        soles_F: Each foot frame's sole points (n, 3) [m] in the foot frame F.
        bodies: Each foot frame's body (the one whose contact wrench is measured), or None.
    """

    def __init__(self, model: pin.Model, soles_F: Mapping[str, np.ndarray],
                 bodies: Mapping[str, str] | None = None):
        self.model, self.data = model, model.createData()
        self.soles_F = dict(soles_F)
        self._fid = {f: model.getFrameId(f) for f in soles_F}
        self._bid = {f: model.getFrameId(b) for f, b in (bodies or {}).items()}

    def update(self, q: npt.ArrayLike, v: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Kinematics at ``q`` (nq,), ``v`` (nv,); the CoM (3,) [m] and its velocity (3,) [m/s] in W."""
        com = pin.centerOfMass(self.model, self.data, np.asarray(q, dtype=float), np.asarray(v, dtype=float))
        pin.updateFramePlacements(self.model, self.data)
        return np.array(com), np.array(self.data.vcom[0])

    def sole_W(self, foot: str) -> np.ndarray:
        """``foot``'s sole points (n, 3) [m] in W at the last :meth:`update`."""
        X = self.data.oMf[self._fid[foot]]
        return self.soles_F[foot] @ X.rotation.T + X.translation

    def body_origin_W(self, foot: str) -> np.ndarray:
        """The origin (3,) [m] in W of ``foot``'s body at the last :meth:`update`."""
        return np.array(self.data.oMf[self._bid[foot]].translation)

    def margins(self, time_s: float, com_W: np.ndarray, vcom_W: np.ndarray, feet: Sequence[str],
                cop_W: np.ndarray | None) -> Balance:
        """The margins of the CoM's capture point and the CoP (None: no normal force) over ``feet``'s soles.

        Args:
            time_s: The state's time [s].
            com_W: The CoM (3,) [m] in W.
            vcom_W: Its velocity (3,) [m/s] in W.
            feet: The feet that carry the robot.
            cop_W: The centre of pressure (3,) [m] in W, or None.
        """
        if not feet:
            return Balance(time_s, (), -np.inf, np.nan)
        soles = np.vstack([self.sole_W(f) for f in feet])
        hull = convex_hull_2d(soles)
        height = max(float(com_W[2] - soles[:, 2].mean()), 0.1)
        capture = com_W[:2] + vcom_W[:2] * np.sqrt(height / GRAVITY_M_S2)
        cop = np.nan if cop_W is None else signed_distance(hull, cop_W)
        return Balance(time_s, tuple(feet), signed_distance(hull, capture), cop)


def measured_cop_W(wrenches_W: np.ndarray, origins_W: np.ndarray, floor_z_m: float) -> np.ndarray | None:
    """The CoP (3,) [m] on the plane ``z = floor_z_m`` of contact wrenches about their bodies' origins.

    Args:
        wrenches_W: Per body (c, 6): force [N], then moment [N m] about the body's origin, world axes.
        origins_W: The bodies' origins (c, 3) [m] in W.
        floor_z_m: Height of the contact plane [m].

    Returns:
        The point where the total moment has no horizontal part, or None without normal force.
    """
    f = wrenches_W[:, :3].sum(axis=0)
    if f[2] < 1e-6:
        return None
    m = (wrenches_W[:, 3:] + np.cross(origins_W, wrenches_W[:, :3])).sum(axis=0)  # about the origin of W
    # p x f + m_free (vertical) = m at p = (x, y, h): m_x = y fz - h fy, m_y = h fx - x fz
    return np.array([(floor_z_m * f[0] - m[1]) / f[2], (m[0] + floor_z_m * f[1]) / f[2], floor_z_m])


class BalanceWatch:
    """Scales the excitation's amplitude down, or stops it into a stance, as the balance margin shrinks.

    Call :meth:`observe` every cycle; read :meth:`scale_at` for the amplitude factor at a time
    and :attr:`stopped_at_s` for the stop.

    Attributes:
        min_margin_m: Smallest margin seen [m] (+inf before any), with ``min_margin_at_s`` [s].
        scalings: (time [s], new scale, margin [m], what was short) of each scaling.
        stopped_at_s: When the excitation was told to stop (None while it runs), with ``stop_reason``.
    """

    def __init__(self) -> None:
        self.min_margin_m = np.inf
        self.min_margin_at_s: float | None = None
        self.scalings: list[tuple[float, float, float, str]] = []
        self.stopped_at_s: float | None = None
        self.stop_reason: str | None = None
        self._scale, self._from, self._since = 1.0, 1.0, -np.inf

    def observe(self, balance: Balance) -> None:
        """Take one cycle's margins; scale or stop when they are short."""
        margin = balance.margin_m
        if margin < self.min_margin_m:
            self.min_margin_m, self.min_margin_at_s = margin, balance.time_s
        if self.stopped_at_s is not None or margin >= SCALE_MARGIN_M:
            return
        t = balance.time_s
        com_worse = balance.com_margin_m <= balance.cop_margin_m or np.isnan(balance.cop_margin_m)
        what = (f"{'CoM' if com_worse else 'CoP'} {margin * 1e3:.1f} mm from the edge of the support "
                f"({' + '.join(balance.feet) or 'none'})")
        if margin < STOP_MARGIN_M or self._scale * SCALE_FACTOR < MIN_SCALE:
            self._from, self._since = self.scale_at(t)[0], t
            self._scale = 0.0
            self.stopped_at_s, self.stop_reason = t, what
        elif t - self._since >= SCALE_HOLD_S:
            self._from, self._since = self.scale_at(t)[0], t
            self._scale *= SCALE_FACTOR
            self.scalings.append((t, self._scale, margin, what))

    def scale_at(self, t: float) -> tuple[float, float, float]:
        """The amplitude factor [-] at time ``t`` [s] and its rates [1/s, 1/s^2].

        The last scale, reached from the one before by a smooth step over :data:`SCALE_RAMP_S`.
        """
        x = (t - self._since) / SCALE_RAMP_S
        if x <= 0.0 or x >= 1.0:
            return (self._from if x <= 0.0 else self._scale), 0.0, 0.0
        jump = self._scale - self._from
        return (self._from + jump * x * x * (3.0 - 2.0 * x), jump * 6.0 * x * (1.0 - x) / SCALE_RAMP_S,
                jump * (6.0 - 12.0 * x) / SCALE_RAMP_S**2)

    def section(self) -> dict[str, Any]:
        """JSON-ready: the smallest margin, each scaling and the stop (null when none happened)."""
        return {
            "min_balance_margin_m": float(self.min_margin_m) if np.isfinite(self.min_margin_m) else None,
            "min_balance_margin_at_s": self.min_margin_at_s,
            "balance_scaled_at_s": self.scalings[0][0] if self.scalings else None,
            "balance_scalings": [{"t_s": t, "scale": s, "margin_m": m, "why": w}
                                 for t, s, m, w in self.scalings],
            "balance_stopped_at_s": self.stopped_at_s, "balance_stop_reason": self.stop_reason,
            "thresholds_m": {"scale": SCALE_MARGIN_M, "stop": STOP_MARGIN_M},
        }
