"""Why the G1's feet slip while it walks: how each stance sole is loaded and how it moves (issue 28).

    MENAGERIE_ROOT=... python bench/walk_soles.py                  # 0.5 m/s, 10 s
    MENAGERIE_ROOT=... python bench/walk_soles.py --speed 0.3 --seconds 10

The job's walker (``g1_walker``: the arm swing, the job's configuration) walks forward in-process;
from 3 s on, every single-support cycle is measured in MuJoCo and in the QP's solution:

* the stance sole's spheres (the Menagerie G1 has four per foot, two at the heel and two at the
  toe): the share of cycles with >= 90 % of the sole's load on one sphere, and with both heel
  spheres carrying < 5 % of it (the heel lifted: the sole turns about its toe line);
* the QP's centre of pressure along the sole, from the sole's centre (the mean of its spheres),
  against the CMP the DCM law commanded (5th and 95th percentiles);
* each stance (the foot held at full weight, as ``g1-walk``'s slip rule counts it): its site's
  largest horizontal drift, its largest yaw change, and its heel's and toe's largest horizontal
  drifts (the bottom of the back and front spheres' mid-points).

A sole that turns about its toe line shows a yaw change of tenths of a radian with a heel drift
several times the toe's. First, as a yardstick, the creep of MuJoCo's soft contacts alone: a block
of the G1's mass on the same four spheres, pushed well inside their friction. ``--cone`` and
``--impratio`` walk on other friction settings of the plant; ``--without-margins`` without the
walker's moment feedforward, friction fraction and torsion bound (``WalkingConfig``). Not a
timing: a diagnostic of the plant's contacts (the walking section of docs/api/walking.rst quotes it).
"""

from __future__ import annotations

import argparse
import math
import sys

import mujoco
import numpy as np

from mbctl.control.loop import run
from mbctl.control.wbc import WalkingConfig, WBCConfig
from mbctl.jobs.g1_walk import g1_walker
from mbctl.robots import load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import FEET, G1_FALL, KEYFRAME, crouched_start, with_palm_sites
from mbctl.sim.contacts import ContactSensor
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.simulator import Simulator

#: MuJoCo's friction cones by name.
CONES = {"pyramidal": int(mujoco.mjtCone.mjCONE_PYRAMIDAL), "elliptic": int(mujoco.mjtCone.mjCONE_ELLIPTIC)}

#: The job's walker without what keeps its soles from turning (issue 28's first walker).
WITHOUT_MARGINS = WalkingConfig(wbc=WBCConfig(on_infeasible="damp"), moment_feedforward=False,
                                friction_fraction=1.0, torsion_m=math.inf)

#: Single-support cycles before this time [s] are not counted (the start and the first steps).
SETTLE_S = 3.0


def _yaw(R: np.ndarray) -> float:
    return math.atan2(R[1, 0], R[0, 0])


def creep(cone: int, impratio: float, push_mg: float = 0.15, seconds: float = 0.5) -> float:
    """How far [m] a 35 kg block on the G1's four sole spheres slides when pushed for ``seconds``.

    The push, ``push_mg`` of its weight, is horizontal at the block's CoM (0.3 m up, above the
    spheres' centre), well inside the spheres' friction (0.6); MuJoCo's soft contacts let it creep.
    """
    spheres = "".join(f'<geom type="sphere" size="0.005" friction="0.6" condim="3" pos="{x} {y} -0.03"/>'
                      for x, y in ((-0.05, 0.025), (-0.05, -0.025), (0.12, 0.03), (0.12, -0.03)))
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><option timestep="0.002" integrator="implicitfast"/><worldbody>'
        '<geom type="plane" size="5 5 .1"/>'
        f'<body pos="0 0 0.04"><freejoint/><inertial pos="0.035 0 0.3" mass="35" diaginertia="1 1 0.3"/>'
        f"{spheres}</body></worldbody></mujoco>")
    m.opt.cone, m.opt.impratio = cone, impratio
    d = mujoco.MjData(m)
    for _ in range(500):  # settle
        mujoco.mj_step(m, d)
    x0 = d.qpos[0]
    d.xfrc_applied[1, 0] = push_mg * 35.0 * 9.81
    for _ in range(round(seconds / m.opt.timestep)):
        mujoco.mj_step(m, d)
    return float(d.qpos[0] - x0)


def soles(speed_m_s: float, seconds: float, cone: int | None = None,
          impratio: float | None = None, config: WalkingConfig | None = None) -> dict[str, float]:
    """Walk ``seconds`` at ``speed_m_s`` forward; the figures of the module doc.

    ``cone`` and ``impratio`` replace the scene's friction cone and impedance ratio; ``config``
    the job's walking configuration.
    """
    robot = position_to_motor(with_palm_sites(load_robot("g1")))
    if cone is not None:
        robot.mj_model.opt.cone = cone
    if impratio is not None:
        robot.mj_model.opt.impratio = impratio
    q0 = crouched_start(robot)
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(q0, np.zeros(robot.nv))
    walker = g1_walker(robot, q0, config=config)
    walker.set_command((speed_m_s, 0.0, 0.0))
    geoms = {f: cs.contact.geoms for f, cs in walker.wbc.contacts.items()}
    monitor = PlantMonitor(sim, geoms, sites=FEET, fall_rule=G1_FALL.reason).attach()
    walker.contact_force = lambda f: monitor.contacts[f].normal_n if monitor.contacts else None
    m, d = sim.model, sim.data
    mg = float(m.body_subtreemass[1]) * float(np.linalg.norm(m.opt.gravity))
    site = {f: m.site(f).id for f in FEET}  # the foot frame F of the spheres' points
    points = {f: walker.wbc.contacts[f].contact.points_F for f in FEET}
    heel = {f: np.flatnonzero(points[f][:, 0] < points[f][:, 0].mean()) for f in FEET}
    spheres = {f: ContactSensor(m, {str(g): [g] for g in geoms[f]}) for f in FEET}  # a group per sphere
    counts = {"single": 0, "one_sphere": 0, "heel_lifted": 0}
    cop, cmp = [], []
    home: dict[str, tuple | None] = dict.fromkeys(FEET)
    worst: dict[str, list[float]] = {f: [0.0] * 4 for f in FEET}
    stances: list[list[float]] = []

    def ends(f: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """The foot's site, heel and toe (horizontal, W) and its yaw."""
        R = d.site_xmat[site[f]].reshape(3, 3)
        p = d.site_xpos[site[f]][:, None] + R @ points[f].T  # the spheres' bottoms (3, n) in W
        back = p[:, heel[f]].mean(axis=1)
        front = p[:, ~np.isin(np.arange(p.shape[1]), heel[f])].mean(axis=1)
        return d.site_xpos[site[f]][:2].copy(), back[:2], front[:2], _yaw(R)

    def on_step(k, state, reference, command) -> bool:
        for f in FEET:  # each stance: from full weight with >= 10 % of m g measured to the release
            cs = walker.wbc.contacts[f]
            if not (cs.active and cs.weight >= 1.0):
                if home[f] is not None and d.time > SETTLE_S:
                    stances.append(worst[f])
                home[f], worst[f] = None, [0.0] * 4
                continue
            if home[f] is None:
                if monitor.contacts[f].normal_n < 0.1 * mg:
                    continue
                home[f] = ends(f)
            now = ends(f)
            drift = [float(np.hypot(*(now[i] - home[f][i]))) for i in range(3)]
            drift.append(abs(math.remainder(now[3] - home[f][3], math.tau)))
            worst[f] = [max(a, b) for a, b in zip(worst[f], drift, strict=True)]
        status = walker.status
        if status.phase != "single" or d.time < SETTLE_S:
            return monitor.fall_reason is not None
        foot = status.stance
        loads = np.array([group[2] for group in spheres[foot].sums(d)])  # each sphere's normal force [N]
        total = loads.sum()
        if total > 0.1 * mg:
            counts["single"] += 1
            counts["one_sphere"] += loads.max() >= 0.9 * total
            counts["heel_lifted"] += loads[heel[foot]].sum() < 0.05 * total
        forces = walker.wbc.last.forces_F[foot]
        centre = points[foot].mean(axis=0)
        if forces[:, 2].sum() > 0:
            cop.append(forces[:, 2] @ (points[foot] - centre) / forces[:, 2].sum())
            X = walker.wbc.last.foot_poses_W[foot]  # the CMP in the foot frame F
            cmp.append(X.rotation.T @ (np.r_[status.cmp_clamped, X.translation[2]] - X.translation) - centre)
        return monitor.fall_reason is not None

    run(sim, walker, None, seconds, on_step=on_step)
    s = np.array(stances) * [1e3, 1e3, 1e3, 1.0]
    cop_x, cmp_x = np.array(cop)[:, 0] * 1e3, np.array(cmp)[:, 0] * 1e3
    n = max(counts["single"], 1)
    med = np.median(s, axis=0)
    return {"fell": monitor.fall_reason is not None, "stances": len(s), "slip_median_mm": float(med[0]),
            "heel_drift_median_mm": float(med[1]), "toe_drift_median_mm": float(med[2]),
            "yaw_median_rad": float(med[3]), "one_sphere_fraction": counts["one_sphere"] / n,
            "heel_lifted_fraction": counts["heel_lifted"] / n,
            "cop_x_p5_mm": float(np.percentile(cop_x, 5)), "cop_x_p95_mm": float(np.percentile(cop_x, 95)),
            "cmp_x_p5_mm": float(np.percentile(cmp_x, 5)), "cmp_x_p95_mm": float(np.percentile(cmp_x, 95))}


def main() -> int:
    """Print the stance soles' figures of one walk."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=0.5, help="forward command (m/s)")
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated time (s)")
    parser.add_argument("--cone", choices=("pyramidal", "elliptic"), default=None,
                        help="the plant's friction cone (default: the scene's, pyramidal)")
    parser.add_argument("--impratio", type=float, default=None,
                        help="the plant's impratio (default: the scene's, 1)")
    parser.add_argument("--without-margins", action="store_true",
                        help="the walker without its moment feedforward, friction fraction and torsion bound")
    args = parser.parse_args()
    for name, cone in CONES.items():
        print(f"creep of a 35 kg block on the four spheres, 0.15 m g for 0.5 s, {name} cones: "
              + ", ".join(f"impratio {r:g} {creep(cone, r) * 1e3:.2f} mm" for r in (1.0, 10.0)))
    cone = None if args.cone is None else CONES[args.cone]
    config = WITHOUT_MARGINS if args.without_margins else None
    r = soles(args.speed, args.seconds, cone, args.impratio, config)
    plant = "" if cone is None and args.impratio is None else f" (cone {args.cone}, impratio {args.impratio})"
    plant += " without the walker's margins" if args.without_margins else ""
    print(f"g1 walking forward at {args.speed:g} m/s for {args.seconds:g} s{plant} (fell: {r['fell']}); "
          f"{r['stances']} stances from {SETTLE_S:g} s on, medians of each stance's largest change:")
    print(f"  site drift {r['slip_median_mm']:.1f} mm; yaw {r['yaw_median_rad']:.3f} rad; "
          f"heel drift {r['heel_drift_median_mm']:.1f} mm; toe drift {r['toe_drift_median_mm']:.1f} mm")
    print(f"  single support: load on one sphere (>= 90 %) in {r['one_sphere_fraction']:.0%} of cycles, "
          f"heel lifted (< 5 %) in {r['heel_lifted_fraction']:.0%}")
    print(f"  the QP's centre of pressure along the sole from its centre: {r['cop_x_p5_mm']:+.0f} to "
          f"{r['cop_x_p95_mm']:+.0f} mm (5th-95th percentile); the commanded CMP: {r['cmp_x_p5_mm']:+.0f} to "
          f"{r['cmp_x_p95_mm']:+.0f} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
