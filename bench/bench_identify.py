"""Identification against a hidden truth: the issue's targets, measured end to end, and its speed.

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_identify.py [--out DIR] [--runs R] [--skip-g1]

1. 2-link torque arm, plant links 20 % heavier (``--plant-error 20``), 30 s excitation:
   identified base parameters against the truth (the plant's model.xml), and ``mbctl demo
   --plant-error 20`` with the nominal model against ``--controller-model identified.xml``
   (and the exact model: the demo without plant error).
2. G1 with a 2 kg payload on the torso (``--payload 2.0@torso_link:0.05,0,0.25``), 30 s standing
   excitation, joint torques only: torso_link's mass and CoM (``--bodies torso_link``), and the
   same with every body free (what the structure allows); g1-wbc squat CoM RMS on the payload
   plant with the nominal controller model against the identified one.
3. Noise: 1 % torque and 1e-4 rad encoder noise on both logs, the same figures.
4. Speed on one core: identification of the 30 s G1 log, median of R runs, torso only and every
   body, with the ratio to the log's duration.

Absolute times depend on the machine's load (printed); the ratios are measured in the same run.
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from mbctl.jobs import options  # noqa: E402
from mbctl.jobs.demo import DEMO  # noqa: E402
from mbctl.jobs.excite import EXCITE  # noqa: E402
from mbctl.jobs.identify import IDENTIFY  # noqa: E402
from mbctl.jobs.runner import run_job  # noqa: E402
from mbctl.robots.identification import ParameterSet  # noqa: E402
from mbctl.robots.identification.inertial import to_inertial  # noqa: E402
from mbctl.robots.identification.pipeline import base_parameter_errors  # noqa: E402
from mbctl.robots.registry import load_robot  # noqa: E402

PAYLOAD = "2.0@torso_link:0.05,0,0.25"
NOISE = {"torque_noise": 1.0, "encoder_noise": 1e-4}


def _run(job, params, folder: Path):
    record = run_job(job, params, folder)
    if record.exit_code:
        raise SystemExit(f"{job.name} failed in {folder}: {record.message or record.summary()}")
    return record


def _report(folder: Path) -> dict:
    return json.loads((folder / "identify_report.json").read_text())


def two_link(out: Path) -> None:
    print("== 2-link torque arm, --plant-error 20 ==")
    log = out / "excite_two_link"
    _run(EXCITE, options.excite("two_link_torque", plant_error=20.0), log)
    truth_set = ParameterSet(load_robot(log / "model.xml"))
    truth = dict(zip(truth_set.names, truth_set.nominal, strict=True))
    for label, extra in (("exact log", {}), ("1 % torque, 1e-4 rad encoder noise", NOISE)):
        folder = out / ("identify_two_link" + ("_noise" if extra else ""))
        _run(IDENTIFY, options.identify([str(log)], **extra), folder)
        report = _report(folder)
        base = report["identifiability"]["base_parameters"]
        coefficients, values = [b["coefficients"] for b in base], [b["identified"] for b in base]
        errors = base_parameter_errors(coefficients, values, truth)
        v = report["validation"]
        print(f"{label}: {len(errors)} base parameters, largest relative error {max(errors):.2e} (target 1 %"
              f"{', x2 with noise' if extra else ''}); validation RMSE nominal "
              f"{v['torque_rmse_nominal']:.3g} N m, identified {v['torque_rmse_identified']:.3g} N m; "
              f"{report['identification_time_s']:.2f} s")
        rms = {}
        for name, params in (("nominal model", options.demo(plant_error=20.0)),
                             ("identified model", options.demo(plant_error=20.0, controller_model=str(
                                 folder / "identified.xml"))),
                             ("exact model (no plant error)", options.demo())):
            rms[name] = _run(DEMO, params, out / f"demo_{name.split()[0]}").values["rms_error_m"]
        print("  mbctl demo --plant-error 20: " + ", ".join(f"{k} {v * 1e3:.4f} mm" for k, v in rms.items())
              + f" (target: identified <= 0.15 mm{', x2 with noise' if extra else ''})")


def _torso_truth(plant_xml: Path) -> tuple[float, np.ndarray]:
    params = ParameterSet(load_robot(plant_xml), ["torso_link", "payload_torso_link"])
    torso, payload = params.body("torso_link"), params.body("payload_torso_link")
    in_joint = torso.transform @ torso.nominal + payload.transform @ payload.nominal
    pi = np.linalg.solve(torso.transform, in_joint)
    m, c, _ = to_inertial(pi)
    return m, c


def g1(out: Path, runs: int) -> None:
    print("== G1, --payload 2.0@torso_link:0.05,0,0.25, 30 s standing excitation, joint torques only ==")
    log = out / "excite_g1"
    t0 = time.perf_counter()
    record = _run(EXCITE, options.excite("g1", payload=PAYLOAD), log)
    print(f"excite: {record.values['duration_s']:.1f} s, fell: {record.values['fell']}, CoM RMS "
          f"{record.values['com_error_rms_m'] * 1e3:.1f} mm, wall {time.perf_counter() - t0:.0f} s")
    m_true, c_true = _torso_truth(log / "model.xml")
    for label, extra in (("exact log", {}), ("1 % torque, 1e-4 rad encoder noise", NOISE)):
        for bodies in ("torso_link", None):
            folder = out / f"identify_g1_{bodies or 'all'}{'_noise' if extra else ''}"
            _run(IDENTIFY, options.identify([str(log)], bodies=bodies, **extra), folder)
            report = _report(folder)
            torso = report["bodies"]["torso_link"]
            dm = torso["mass_kg"]["identified"] - m_true
            dc = np.linalg.norm(np.array(torso["com_m"]["identified"]) - c_true)
            total = sum(b["mass_kg"]["identified"] for b in report["bodies"].values())
            n = report["identifiability"]["parameters"]
            what = "torso only" if bodies else f"every body ({n} params)"
            print(f"{label}, {what}: torso mass {torso['mass_kg']['identified']:.4f} kg (truth {m_true:.4f}, "
                  f"error {dm * 1e3:+.1f} g, std {torso['mass_kg']['std'] * 1e3:.1f} g), CoM error "
                  f"{dc * 1e3:.2f} mm (targets 100 g, 10 mm{', x2 with noise' if extra else ''})"
                  + ("" if bodies else f"; total mass {total:.3f} kg"))
    wbc_squat(out, log)
    times = {"torso only": [], "every body": []}
    for _ in range(runs):
        for name, bodies in (("torso only", "torso_link"), ("every body", None)):
            t0 = time.perf_counter()
            _run(IDENTIFY, options.identify([str(log)], bodies=bodies), out / "identify_g1_timing")
            times[name].append(time.perf_counter() - t0)
    duration = record.values["duration_s"]
    for name, ts in times.items():
        med = statistics.median(ts)
        print(f"speed, {name}: identify job {med:.2f} s median of {runs} (range {min(ts):.2f}-"
              f"{max(ts):.2f}), {med / duration:.2f} x the log's {duration:.0f} s (target < 30 s, one core)")


def wbc_squat(out: Path, log: Path) -> None:
    """g1-wbc squat on the payload plant, nominal controller model against the identified one."""
    from mbctl.jobs.g1_wbc import G1_WBC, WBCParams
    from mbctl.jobs.model_options import ModelOptions

    rms = {}
    for name, model in (("nominal", None), ("identified", out / "identify_g1_torso_link" / "identified.xml")):
        params = WBCParams("squat", models=ModelOptions(PAYLOAD, 0.0, model and str(model)))
        record = run_job(G1_WBC, params, out / f"wbc_squat_{name}")
        rms[name] = record.values["com_error_rms_m"]
    print(f"g1-wbc squat on the payload plant: CoM RMS nominal model {rms['nominal'] * 1e3:.2f} mm, "
          f"identified model {rms['identified'] * 1e3:.2f} mm")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_identify"))
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--skip-g1", action="store_true")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    print(f"load average before: {open('/proc/loadavg').read().split()[:3]}")
    two_link(args.out)
    if not args.skip_g1:
        g1(args.out, args.runs)
    print(f"load average after: {open('/proc/loadavg').read().split()[:3]}")


if __name__ == "__main__":
    main()
