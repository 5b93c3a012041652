"""Identify an arm's inertial parameters from its log, write them back, check both engines carry them.

Pipeline, all on the public API:

1. A hidden truth: the plant's links are 20 % heavier than the model (``scale_link_masses``).
2. ``design_excitation``: a Fourier-series trajectory optimised for the regressor's condition
   number within the joint, speed and torque limits (on the nominal model: all a design knows).
3. ``ComputedTorque`` (nominal model) tracks it on the plant through ``run``; the log is a
   ``RecordedLog`` (time, q, v and the torques sent: the arm's motors apply them as they are).
4. ``identify``: Pinocchio's regressor, base parameters, the physically consistent estimate
   regularised toward the nominal model, validated on the log's last quarter.
5. ``identified_xml``: the robot's MJCF with the identified values, loaded back as a robot and
   cross-checked (Pinocchio against MuJoCo).

Run::

    python examples/09_identify_your_arm.py              # 20 s of excitation
    python examples/09_identify_your_arm.py --duration 6

Exits 1 if an identified base parameter is more than 1 % off the hidden truth.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from mbctl.control import ComputedTorque, gains_from_frequency, run
from mbctl.planners.excitation import design_excitation
from mbctl.robots import load_robot
from mbctl.robots.crosscheck import crosscheck
from mbctl.robots.edits import scale_link_masses
from mbctl.robots.identification import ParameterSet, RecordedLog, identified_xml, identify
from mbctl.robots.identification.pipeline import base_parameter_errors
from mbctl.sim import Simulator

MAX_BASE_ERROR = 0.01  # 1 %


def main() -> int:
    """Excite, identify, write back, check; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0, help="simulated time of the excitation [s]")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")

    robot = load_robot("two_link_torque", gravity=True)  # the nominal model
    plant = scale_link_masses(robot, 1.2)                  # the truth, hidden from everything below
    joints = ("shoulder", "elbow")
    design = design_excitation(robot, joints, np.zeros(2), period_s=5.0, harmonics=4, n_samples=40,
                               max_iterations=20)
    print(f"excitation: condition number {design.condition_number:.3g} (random start "
          f"{design.initial_condition_number:.3g}), {design.structural_rank} identifiable combinations")
    sim = Simulator(plant)
    controller = ComputedTorque(plant, gains_from_frequency(30.0, 1.0), pin_model=robot.pin_model)
    trajectory = design.trajectory.trajectory(sim.control_period_s, args.duration)
    log = run(sim, controller, trajectory, args.duration)
    recorded = RecordedLog(log.t_s, log.q, log.v, log.command, joints)

    ident = identify(robot, [recorded])
    truth = dict(zip(ParameterSet(plant).names, ParameterSet(plant).nominal, strict=True))
    names = ident.params.names
    base = [b.coefficients for b in ident.data.base]
    errors = base_parameter_errors(base, [b.value(ident.theta, names) for b in ident.data.base], truth)
    for b, err in zip(ident.data.base, errors, strict=True):
        print(f"  {b.expression():55s} identified {b.value(ident.theta, names):+.5f}, error {err:.1e}")
    for body in ident.params.bodies:
        print(f"  {body.name}: mass {body.nominal[0]:.3f} -> {ident.theta[body.columns][0]:.3f} kg "
              f"(std {ident.estimate.std[body.columns][0]:.2g}; the truth {truth[body.name + '.m']:.3f})")
    print(f"validation torque RMSE: nominal {ident.nominal_prediction.rmse():.3g} N m, identified "
          f"{ident.identified_prediction.rmse():.3g} N m")

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "identified.xml"
        path.write_text(identified_xml(robot, ident.params, ident.theta))
        report = crosscheck(load_robot(path), n_states=20)
        worst = max(q.max_rel_error for q in report.quantities if q.status == "pass")
        verdict = "PASS" if report.passed else "FAIL"
        print(f"identified.xml: cross-check {verdict}, max rel. error {worst:.1e}")
    ok = errors.max() <= MAX_BASE_ERROR and report.passed
    print(f"largest base-parameter error {errors.max():.1e} (bound {MAX_BASE_ERROR:g}): "
          f"{'ok' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
