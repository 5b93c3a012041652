"""The largest push the G1's walker can recover from at all: an N-step capturability bound (issue 28).

    MENAGERIE_ROOT=... python bench/push_bound.py                    # hold 0.08 s, early in a swing
    MENAGERIE_ROOT=... python bench/push_bound.py --hold 0.1 --steps 1,2,3,6

Not a timing: the linear inverted pendulum (LIPM) of the job's walker (``g1_walker``), with its
limits read from the model and its configuration, and a linear program per direction:

* **The pendulum.** ``omega = sqrt(g / z_c)``, ``z_c`` the walking CoM height (``com_height_m``); the
  mass is the plant's. The DCM ``xi = c + v / omega`` obeys ``xi' = omega (xi - p) + F / (m omega)``
  with ``p`` the CMP, anywhere in the stance sole's polygon grown by ``cmp_outside_m`` (the hip
  strategy; as a box: optimistic). A force ``F = J / h`` held ``h`` from the push's start moves the
  DCM at a touchdown ``T`` later by ``J u (e^(omega T) - e^(omega (T - h))) / (h m omega^2)``.
* **The state at the push.** Steady LIPM walking at ``--speed`` with the walker's step period ``T_s``
  (single + double support) and nominal width ``w``: at the switch the DCM is ``s / (e^(omega T_s) -
  1)`` ahead of the stance sole's centre (``s = v T_s``) and ``w / (e^(omega T_s) + 1)`` toward the
  swing side; the push starts ``--after`` later (half the double support and 10 % of the swing for
  the ``early`` push).
* **The steps.** The first is the swing foot's (the side ``+y``: 90 deg pushes toward it, 270 deg
  toward the stance side), then the feet alternate. Each footstep, from the one before, lies in the
  step adaptation's pushed reach (:mod:`~mbctl.control.wbc.step_adaptation`): the 8-gon in the
  half-ellipses with semi-axes ``max_forward_m`` / ``max_backward_m`` and ``pushed_outward_fraction
  r`` about the nominal stance, within the box ``[-max_backward_m, max_forward_m]`` and ``w +
  pushed_outward_fraction r`` outward, and either ``min_width_m`` or more beside the stance foot or
  crossed ``sole length + cross_over_clearance_m`` ahead or behind it (the cross-over step; each
  choice an LP, all tried). ``--reach kinematic`` replaces the forward and backward semi-axes and
  the outward one by the leg's geometric ``2 r`` (``r`` from :func:`~mbctl.planners.footsteps.
  step_limits_from_model`: ``REACH_USE`` and ``BACKWARD_FRACTION`` dropped).
* **The timing.** The first touchdown comes ``max(t_lo + T_min, t + min_swing_left_s, t_lo + (t - t_lo
  + d / v_max) / f_h)`` (the walker's timing floor ``min_single_support_s``, its least swing left,
  and ``max_swing_speed_m_s`` over the swing's horizontal fraction, ``d`` the foot's way to its
  footstep); a later step takes half a ramp of double support (the hurried release) and the same
  floor. ``--timing floor`` drops the swing-speed bound. The distances depend on the footsteps,
  so the timing and the LP are iterated to a fixed point.
* **Captured** after N steps: the DCM at the N-th touchdown inside the new stance's CMP region (it
  can then stand). The LP maximises the impulse ``J`` over the footsteps and the CMPs.

The answer is an upper bound for this walker: the whole body adds what the LIPM leaves out (the
swing leg's momentum, the torque limits, a foot that lands late), and no walker with these limits
recovers a larger push.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

G = 9.81


@dataclass(frozen=True)
class Model:
    """The walker's numbers the bound needs (units in the names)."""

    mass_kg: float
    omega_1_s: float
    forward_m: float
    backward_m: float
    outward_m: float
    width_m: float
    min_width_m: float
    cross_ahead_m: float
    cmp_box_m: tuple[float, float, float, float]  # x min, x max, y min, y max in the foot frame
    sole_centre_x_m: float
    single_s: float
    double_s: float
    ramp_s: float
    min_single_s: float
    min_swing_left_s: float
    swing_speed_m_s: float
    horizontal_fraction: float
    reach_r_m: float


def g1_model() -> Model:
    """The numbers from the job's G1 walker (the Menagerie G1, the job's configuration)."""
    from mbctl.jobs.g1_walk import g1_walker
    from mbctl.robots.g1 import crouched_start, whole_body_g1
    from mbctl.robots.registry import load_robot

    robot = whole_body_g1(load_robot("g1"))
    walker = g1_walker(robot, crouched_start(robot), gait="normal")  # (docs/api/walking.rst's figures)
    lim, cfg = walker.limits, walker.config
    xs = [x for x, _ in lim.sole_xy_m]
    ys = [y for _, y in lim.sole_xy_m]
    grow = cfg.cmp_outside_m
    r = lim.max_outward_m  # LATERAL_FRACTION r, the fraction 1
    return Model(float(robot.mj_model.body_subtreemass[1]), math.sqrt(G / cfg.com_height_m),
                 lim.max_forward_m, lim.max_backward_m, cfg.pushed_outward_fraction * lim.max_outward_m,
                 lim.nominal_width_m, lim.min_width_m, max(xs) - min(xs) + cfg.cross_over_clearance_m,
                 (min(xs) - grow, max(xs) + grow, min(ys) - grow, max(ys) + grow), 0.5 * (min(xs) + max(xs)),
                 cfg.timing.single_support_s, cfg.timing.double_support_s, cfg.ramp_s,
                 cfg.min_single_support_s, cfg.min_swing_left_s, cfg.max_swing_speed_m_s,
                 cfg.swing_horizontal_fraction, r)


def kinematic(m: Model) -> Model:
    """The same with the leg's geometric reach: 2 r forward, backward and outward."""
    from dataclasses import replace

    return replace(m, forward_m=2 * m.reach_r_m, backward_m=2 * m.reach_r_m, outward_m=2 * m.reach_r_m)


def regions(m: Model, side: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The step's reach from the stance footstep, ``A x <= b``: beside it, crossed ahead, crossed behind."""
    k = np.arange(8) * math.pi / 4
    u = np.column_stack([np.cos(k), np.sin(k)])
    vx = np.where(u[:, 0] >= 0, m.forward_m, m.backward_m) * u[:, 0]
    verts = np.column_stack([vx, m.outward_m * u[:, 1] + side * m.width_m])
    edge = np.roll(verts, -1, axis=0) - verts
    normal = np.column_stack([edge[:, 1], -edge[:, 0]])
    A = [*normal, [1, 0], [-1, 0], [0, side]]
    b = [*(normal * verts).sum(axis=1), m.forward_m, m.backward_m, m.width_m + m.outward_m]
    beside = (np.array([*A, [0, -side]]), np.array([*b, -m.min_width_m]))
    ahead = (np.array([*A, [-1, 0]]), np.array([*b, -m.cross_ahead_m]))
    behind = (np.array([*A, [1, 0]]), np.array([*b, -m.cross_ahead_m]))
    return [beside, ahead, behind]


def start_state(m: Model, speed_m_s: float, after_s: float) -> np.ndarray:
    """The DCM (2,) [m] from the stance sole's centre at the push (+y: the swing side)."""
    period = m.single_s + m.double_s
    e = math.exp(m.omega_1_s * period)
    b0 = np.array([speed_m_s * period / (e - 1), m.width_m / (e + 1)])
    return b0 * math.exp(m.omega_1_s * after_s)


def best(m: Model, xi0: np.ndarray, u: np.ndarray, hold_s: float, times: list[float],
         choice: tuple[int, ...]) -> tuple[float, np.ndarray] | None:
    """Max J [N s] for touchdowns ``times`` [s] apart (the first from the push) and one region per step.

    Variables: J, the footsteps f_1..f_N (from the stance footstep at 0), the CMPs p_0..p_N-1; the last
    touchdown's DCM inside f_N's CMP region.
    """
    n, w = len(times), m.omega_1_s
    nv = 1 + 2 * n + 2 * n
    fi = lambda k: 1 + 2 * (k - 1)  # noqa: E731 - f_k, k = 1..n
    pi = lambda k: 1 + 2 * n + 2 * k  # noqa: E731 - p_k, k = 0..n-1
    A_ub, b_ub = [], []
    x0, x1, y0, y1 = m.cmp_box_m

    def in_box(pcol: int, fcol: int | None, point: tuple[list[float], float] | None = None) -> None:
        # the point p (columns pcol) within the CMP box about the footstep f (columns fcol, or the origin)
        for axis, lo, hi in ((0, x0, x1), (1, y0, y1)):
            for sign, bound in ((1.0, hi), (-1.0, -lo)):
                row = np.zeros(nv)
                if point is None:
                    row[pcol + axis] = sign
                    const = 0.0
                else:  # the DCM, an affine function of the variables
                    row += sign * np.asarray(point[0][axis])
                    const = sign * point[1][axis]
                if fcol is not None:
                    row[fcol + axis] -= sign  # (the footstep's CMP box is about the foot frame)
                A_ub.append(row)
                b_ub.append(bound - const)

    for k in range(n):
        in_box(pi(k), fi(k) if k else None)
    for k in range(1, n + 1):  # each step from the one before, in its region
        side = 1 if k % 2 else -1
        A, b = regions(m, side)[choice[k - 1]]
        for a_row, b_val in zip(A, b, strict=True):
            row = np.zeros(nv)
            row[fi(k):fi(k) + 2] += a_row
            if k > 1:
                row[fi(k - 1):fi(k - 1) + 2] -= a_row
            A_ub.append(row)
            b_ub.append(b_val)
    # the DCM at each touchdown: xi_k = e xi_{k-1} + (1 - e) p_{k-1} (+ the push in the first)
    coef = np.zeros((2, nv))
    const = xi0.copy()
    for k, t in enumerate(times):
        e = math.exp(w * t)
        coef, const = e * coef, e * const
        coef[:, pi(k):pi(k) + 2] += (1 - e) * np.eye(2)
        if k == 0:
            gain = (math.exp(w * t) - math.exp(w * (t - hold_s))) / (hold_s * m.mass_kg * w * w)
            coef[:, 0] += gain * u
    rows = [list(coef[0]), list(coef[1])]
    in_box(0, fi(n), (rows, const))
    c = np.zeros(nv)
    c[0] = -1.0
    res = linprog(c, A_ub=np.array(A_ub), b_ub=np.array(b_ub), bounds=[(0, 500)] + [(None, None)] * (nv - 1),
                  method="highs")
    if res.status != 0:
        return None
    return float(res.x[0]), res.x


def bound(m: Model, direction_deg: float, steps: int, hold_s: float, speed: float, after_s: float,
          speed_bound: bool) -> tuple[float, list[float], np.ndarray | None]:
    """The largest impulse [N s] recoverable in ``steps`` steps, its touchdown times and footsteps."""
    u = np.array([math.cos(math.radians(direction_deg)), math.sin(math.radians(direction_deg))])
    xi0 = start_state(m, speed, after_s)
    into = after_s - 0.5 * m.double_s  # time into the swing at the push
    # the swing foot at the push: from where it lifted toward its nominal footstep (2 s ahead), at a
    # constant speed over the swing's horizontal part (a smooth path has moved less: optimistic)
    lifted = np.array([-speed * (m.single_s + m.double_s), m.width_m])
    progress = min(max(into, 0.0) / (m.horizontal_fraction * m.single_s), 1.0)
    swing_from = lifted + progress * np.array([2 * speed * (m.single_s + m.double_s), 0.0])
    first_floor = max(m.min_single_s - into, m.min_swing_left_s)
    later_floor = 0.5 * m.ramp_s + m.min_single_s
    times = [first_floor] + [later_floor] * (steps - 1)
    found: tuple[float, np.ndarray | None] = (0.0, None)
    for _ in range(12):
        found = (0.0, None)
        for choice in itertools.product(range(3), repeat=steps):
            r = best(m, xi0, u, hold_s, times, choice)
            if r is not None and r[0] > found[0]:
                found = r
        if not speed_bound or found[1] is None:
            break
        f = found[1][1:1 + 2 * steps].reshape(steps, 2)
        prev = [swing_from, np.zeros(2), *f[:-1]]  # where each swing foot comes from
        new = []
        for k in range(steps):
            way_s = float(np.linalg.norm(f[k] - prev[k])) / m.swing_speed_m_s / m.horizontal_fraction
            if k == 0:
                into_now = max(into, 0.0)  # (a push in double support: the swing starts -into later)
                new.append(max(first_floor, into_now / m.horizontal_fraction + way_s - into))
            else:
                new.append(0.5 * m.ramp_s + max(m.min_single_s, way_s))
        if np.allclose(new, times, atol=1e-4):
            break
        times = [0.5 * (a + b) for a, b in zip(times, new, strict=True)]
    feet = None if found[1] is None else found[1][1:1 + 2 * steps].reshape(steps, 2)
    return found[0], times, feet


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hold", type=float, default=0.08, help="the push's hold [s]")
    ap.add_argument("--speed", type=float, default=0.3, help="the walking speed [m/s]")
    ap.add_argument("--after", type=float, default=None,
                    help="the push's start after the switch [s] (default: half the double support and 10 %% "
                         "of the swing, the early push)")
    ap.add_argument("--steps", default="1,2,3,6", help="N, comma-separated")
    ap.add_argument("--reach", choices=("walker", "kinematic"), default="walker")
    ap.add_argument("--timing", choices=("walker", "floor"), default="walker",
                    help="walker: the timing floor and the swing-speed bound; floor: the floor alone")
    args = ap.parse_args(argv)
    m = g1_model()
    if args.reach == "kinematic":
        m = kinematic(m)
    after = args.after if args.after is not None else 0.5 * m.double_s + 0.1 * m.single_s
    xi0 = start_state(m, args.speed, after)
    print(f"m {m.mass_kg:.2f} kg, omega {m.omega_1_s:.3f} 1/s; reach forward {m.forward_m:.3f}, backward "
          f"{m.backward_m:.3f}, outward {m.outward_m:.3f} m beyond the width {m.width_m:.3f} (min "
          f"{m.min_width_m:.3f}, crossing {m.cross_ahead_m:.3f} ahead/behind); CMP box x "
          f"[{m.cmp_box_m[0]:.3f}, {m.cmp_box_m[1]:.3f}], y [{m.cmp_box_m[2]:.3f}, {m.cmp_box_m[3]:.3f}] m; "
          f"timing floor {m.min_single_s} s, swing speed {m.swing_speed_m_s} m/s ({args.timing}); DCM at the "
          f"push ({xi0[0]:.3f}, {xi0[1]:.3f}) m from the stance sole's centre; hold {args.hold} s")
    steps = [int(s) for s in args.steps.split(",")]
    print("dir  " + "  ".join(f"N={n:<2d}" for n in steps) + "   (impulse, N s; the N-step's first footstep "
          "and touchdown)")
    for d in range(0, 360, 45):
        cells, last = [], None
        for n in steps:
            j, times, feet = bound(m, d, n, args.hold, args.speed, after, args.timing == "walker")
            cells.append(f"{j:5.1f}")
            last = (times, feet)
        times, feet = last
        first = "" if feet is None else (f"   f1 ({feet[0][0]:+.3f}, {feet[0][1]:+.3f}) m at "
                                         f"{times[0]:.3f} s, then every {times[-1]:.3f} s")
        print(f"{d:3d}  " + "  ".join(cells) + first)
    return 0


if __name__ == "__main__":
    sys.exit(main())
