"""Honest standard deviations: identified values against a known hidden truth, on two arms.

Logs are recorded with ``mbctl excite``'s job on a plant hiding a payload or a friction change
(noise-free: the residual is the processing's, systematic). The reported covariance must put
>= 90 % of the identified (base) parameters within 3 standard deviations of the truth; the
white-noise (Laplace) covariance did not (friction 11 sigma off on the 3-link arm).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from mbctl.jobs import options
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.ident_log import read_run
from mbctl.jobs.identify import load_nominal
from mbctl.jobs.runner import run_job
from mbctl.robots.identification import IdentifyOptions, ParameterSet, identify
from mbctl.robots.identification.summary import base_summaries
from mbctl.robots.identification.uncertainty import bartlett_long_run, upper_bound
from mbctl.robots.registry import load_robot

ROOT = Path(__file__).resolve().parents[3]
TWO_LINK = ROOT / "robots" / "assets"
THREE_LINK = ROOT / "tests" / "robots" / "assets" / "three_link_arm.xml"

#: Hidden payloads (KG@BODY:X,Y,Z) and joint friction (damping [N m s/rad], frictionloss [N m]).
PAYLOAD = {"two": "0.4@link2:0.1,0.02,0", "three": "0.5@fore:0.2,0.02,0.03"}
FRICTION = {"two": (0.05, 0.1), "three": (0.2, 0.3)}


def _friction_plant(arm: str, folder: Path) -> Path:
    """The arm's MJCF with friction on every joint (the nominal model has none)."""
    damping, loss = FRICTION[arm]
    folder.mkdir(parents=True)
    if arm == "two":
        shutil.copy(TWO_LINK / "two_link_torque.xml", folder / "two_link_torque.xml")
        text = (TWO_LINK / "two_link_arm.xml").read_text()
        old = 'armature="0.002"'
        (folder / "two_link_arm.xml").write_text(
            text.replace(old, f'{old} damping="{damping}" frictionloss="{loss}"'))
        return folder / "two_link_torque.xml"
    old = 'armature="0.005"'
    path = folder / "three_link_arm.xml"
    path.write_text(THREE_LINK.read_text().replace(old, f'{old} damping="{damping}" frictionloss="{loss}"'))
    return path


def _truth(params: ParameterSet, nominal, plant) -> np.ndarray:
    """The plant's parameters in ``params``' columns.

    A hidden change of a joint's inertia (a payload) is the difference of the two Pinocchio joint
    inertias, put on the first identified body of that joint; friction is the plant's.
    """
    truth = params.nominal.copy()
    seen = set()
    for b in params.bodies:
        if b.joint_id in seen:
            continue
        seen.add(b.joint_id)
        change = (plant.pin_model.inertias[b.joint_id].toDynamicParameters()
                  - nominal.pin_model.inertias[b.joint_id].toDynamicParameters())
        truth[b.columns] += np.linalg.solve(b.transform, change)
    plant_params = ParameterSet(plant, friction=True)
    for i, name in enumerate(params.names):
        if name.endswith((".fv", ".fc")):
            truth[i] = plant_params.nominal[plant_params.names.index(name)]
    return truth


def _case(arm: str, hidden: str, folder: Path):
    """Excite the arm with a hidden change, identify it (friction too): (identification, truth)."""
    nominal_name = "two_link_torque" if arm == "two" else str(THREE_LINK)
    robot, payload = nominal_name, None
    if hidden == "friction":
        robot = str(_friction_plant(arm, folder / "plant"))
    else:
        payload = PAYLOAD[arm]
    run = folder / "run"
    record = run_job(EXCITE, options.excite(robot, duration=10.0, period=5.0, harmonics=4, seed=1,
                                            payload=payload), run)
    assert record.exit_code == 0, record.message
    log, section = read_run(run)
    nominal = load_nominal(options.identify([str(run)], robot=nominal_name), section)
    plant = (load_robot(run / "model.xml") if hidden == "payload"
             else load_nominal(options.identify([str(run)], robot=robot), section))
    ident = identify(nominal, [log], IdentifyOptions(friction=True))
    return ident, _truth(ident.params, nominal, plant)


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    root = tmp_path_factory.mktemp("honest")
    return {(arm, hidden): _case(arm, hidden, root / f"{arm}_{hidden}")
            for arm in ("two", "three") for hidden in ("payload", "friction")}


def _z(ident, truth, covariance) -> np.ndarray:
    """(identified - true) / std of every base parameter of the data."""
    names = ident.params.names
    out = []
    for b in ident.data.base:
        d = np.zeros(len(names))
        for name, c in b.coefficients.items():
            d[names.index(name)] = c
        out.append(d @ (ident.theta - truth) / np.sqrt(d @ covariance @ d))
    return np.array(out)


def test_at_least_90_percent_of_identified_parameters_are_within_3_std_of_the_truth(cases):
    z = np.concatenate([_z(ident, truth, ident.estimate.covariance) for ident, truth in cases.values()])
    assert len(z) == 10 + 8 + 21 + 21  # base parameters (with friction): 2-link twice, 3-link twice
    assert np.mean(np.abs(z) <= 3.0) >= 0.9, np.round(z, 1)
    # friction, the hardest (a soft constraint in the plant, a smooth sign in the model), per case
    for arm in ("two", "three"):
        ident, truth = cases[arm, "friction"]
        friction = [i for i, n in enumerate(ident.params.names) if n.endswith((".fv", ".fc"))]
        z_f = (ident.theta - truth)[friction] / ident.estimate.std[friction]
        assert np.all(np.abs(z_f) <= 3.0), (arm, np.round(z_f, 1))


def test_the_white_noise_covariance_was_not_honest_and_the_honest_one_is_not_vacuous(cases):
    """The Laplace stds miss the truth by many sigma on friction; the honest ones stay informative."""
    ident, truth = cases["three", "friction"]
    assert np.abs(_z(ident, truth, ident.uncertainty.laplace)).max() > 8.0
    for key, (ident, _) in cases.items():
        rel = [s.std / abs(s.identified) for s in base_summaries(ident) if abs(s.identified) > 1e-3]
        assert np.median(rel) < 0.1, (key, rel)  # a few percent: not a bound made by inflating
        for s in base_summaries(ident):  # the report's std is the reported covariance's
            d = np.zeros(ident.params.n)
            for name, c in s.coefficients.items():
                d[ident.params.names.index(name)] = c
            assert s.std == pytest.approx(np.sqrt(d @ ident.estimate.covariance @ d), rel=1e-9)


def test_upper_bound_dominates_both_covariances():
    rng = np.random.default_rng(3)
    A, B = rng.standard_normal((5, 3)), rng.standard_normal((5, 4))
    C1, C2 = A @ A.T, B @ B.T
    C = upper_bound(C1, C2)
    assert np.linalg.eigvalsh(C - C1).min() > -1e-9 * np.abs(C).max()
    assert np.linalg.eigvalsh(C - C2).min() > -1e-9 * np.abs(C).max()
    assert np.trace(C) <= np.trace(C1 + C2) + 1e-9  # no looser than their sum
    np.testing.assert_allclose(upper_bound(C1, np.zeros((5, 5))), C1, atol=1e-9 * np.abs(C1).max())


def test_bartlett_long_run_is_the_newey_west_sum():
    """The window-sum form equals ``Gamma_0 + sum_l (1 - l / (L + 1)) (Gamma_l + Gamma_l^T)``."""
    x = np.random.default_rng(0).standard_normal((57, 4))
    lags = 9
    expected = x.T @ x
    for lag in range(1, lags + 1):
        gamma = x[lag:].T @ x[:-lag]
        expected += (1.0 - lag / (lags + 1)) * (gamma + gamma.T)
    np.testing.assert_allclose(bartlett_long_run(x, lags), expected, rtol=1e-12, atol=1e-12)
