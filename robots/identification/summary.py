"""What an identification found, per body and per joint, with its uncertainty: the report's numbers.

A body's 10 parameters ``pi = (m, h, I)`` (:mod:`mbctl.robots.identification.inertial`, ``h = m c``)
become what a modeller reads: the mass m [kg], the centre of mass ``c = h / m`` [m] in the body
frame, and the rotational inertia about the CoM [kg m^2] in the body axes. The estimate's
covariance ``Sigma`` (10, 10) of ``pi`` (:class:`~mbctl.robots.identification.estimate.Estimate`)
gives the mass's standard deviation directly and the CoM's by the delta method (first order in
the parameters' errors)::

    J_c = dc/dpi = [ -h / m^2 | I_3 / m | 0_{3x6} ]   (3, 10)
    Cov(c) = J_c Sigma J_c^T                           (3, 3) [m^2]

Each reported number also says how the data determined it (:func:`excitation_status`, from the
identifiability of the training data: the relative excitation of its direction in parameter
space, a CoM component's being ``J_c``'s row): ``"identified"``, ``"weakly excited"`` (the log
barely moves it: its value leans on small, systematic parts of the torques; do not trust it
beyond its std) or ``"not identified"`` (the prior decides it).

which holds while the mass's relative error is small (``std(m) / m`` << 1); a Monte-Carlo check
is in tests/robots/identification/test_summary.py.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from mbctl.robots.identification.exceptions import IdentificationError
from mbctl.robots.identification.identifiability import WEAK_RTOL, Identifiability
from mbctl.robots.identification.inertial import Inertial, to_inertial
from mbctl.robots.identification.pipeline import Identification

__all__ = ["BaseSummary", "BodySummary", "ParameterSummary", "base_summaries", "body_summary",
           "com_covariance", "com_std", "excitation_status", "joint_summaries"]


#: The statuses of :func:`excitation_status`.
IDENTIFIED, WEAKLY_EXCITED, NOT_IDENTIFIED = "identified", "weakly excited", "not identified"


def excitation_status(data: Identifiability, direction: npt.ArrayLike) -> str:
    """How the data determine ``direction . theta``: identified, weakly excited or not identified.

    Args:
        data: The identifiability of the training data.
        direction: (n,) in the parameters' units (a unit vector for one parameter).
    """
    e = data.excitation(np.asarray(direction, dtype=float))
    return NOT_IDENTIFIED if e <= 0.0 else WEAKLY_EXCITED if e < WEAK_RTOL else IDENTIFIED


def _com_jacobian(pi: np.ndarray) -> np.ndarray:
    m = float(pi[0])
    J = np.zeros((3, 10))
    J[:, 0] = -pi[1:4] / m**2
    J[:, 1:4] = np.eye(3) / m
    return J


def com_covariance(pi: npt.ArrayLike, covariance: npt.ArrayLike) -> np.ndarray:
    """Covariance (3, 3) [m^2] of the CoM ``c = h / m`` in the body frame, by the delta method.

    Args:
        pi: A body's parameters (10,) ``(m, h, I)`` [kg, kg m, kg m^2], Pinocchio's order.
        covariance: Their covariance (10, 10), in the same units squared.

    Raises:
        IdentificationError: Misshaped inputs, or a mass that is not positive and finite.
    """
    p = np.asarray(pi, dtype=float)
    cov = np.asarray(covariance, dtype=float)
    if p.shape != (10,) or cov.shape != (10, 10):
        raise IdentificationError(f"com_covariance needs pi (10,) and covariance (10, 10); got {p.shape} "
                                  f"and {cov.shape}")
    m = float(p[0])
    if not (np.isfinite(m) and m > 0.0):
        raise IdentificationError(f"the CoM c = h / m needs a positive mass; got m = {m!r} kg")
    J = _com_jacobian(p)
    return J @ cov @ J.T


def com_std(pi: npt.ArrayLike, covariance: npt.ArrayLike) -> np.ndarray:
    """Standard deviation (3,) [m] of each CoM coordinate in the body frame (:func:`com_covariance`).

    Raises:
        IdentificationError: As :func:`com_covariance`.
    """
    return np.sqrt(np.maximum(np.diag(com_covariance(pi, covariance)), 0.0))


class BodySummary(NamedTuple):
    """One body, nominal and identified, as a modeller writes it.

    Attributes:
        name: The body's name.
        nominal: Mass [kg], CoM (3,) [m] in the body frame, inertia (3, 3) [kg m^2] about the CoM in
            the body axes, of the nominal model.
        identified: The same, identified.
        mass_std_kg: Standard deviation of the identified mass [kg].
        com_std_m: Standard deviation (3,) of the identified CoM [m] in the body frame (delta method).
        mass_status: How the data determined the mass (:func:`excitation_status`).
        com_status: The same (3,) for each CoM coordinate.
    """

    name: str
    nominal: Inertial
    identified: Inertial
    mass_std_kg: float
    com_std_m: np.ndarray
    mass_status: str = IDENTIFIED
    com_status: tuple[str, str, str] = (IDENTIFIED, IDENTIFIED, IDENTIFIED)


def body_summary(ident: Identification, name: str) -> BodySummary:
    """The body ``name`` of an identification, nominal and identified, with the uncertainty.

    Raises:
        UnknownNameError: ``name`` is not an identified body.
        IdentificationError: An identified mass that is not positive.
    """
    block = ident.params.body(name)
    cols = block.columns
    est = ident.estimate
    theta = ident.theta[cols]
    n = ident.params.n

    def status(local: np.ndarray) -> str:
        d = np.zeros(n)
        d[cols] = local
        return excitation_status(ident.data, d)

    J = _com_jacobian(theta) if theta[0] > 0 else np.zeros((3, 10))
    com = (status(J[0]), status(J[1]), status(J[2]))
    return BodySummary(name, to_inertial(block.nominal), to_inertial(theta), float(est.std[cols][0]),
                       com_std(theta, est.covariance[cols, cols]), status(np.eye(10)[0]), com)


class ParameterSummary(NamedTuple):
    """One scalar parameter, nominal and identified (units those of the parameter).

    Attributes:
        nominal: The nominal model's value.
        identified: The estimate.
        std: Its standard deviation.
        status: How the data determined it (:func:`excitation_status`).
    """

    nominal: float
    identified: float
    std: float
    status: str = IDENTIFIED


#: The joint parameters a summary names, with their units: viscous friction [N m s/rad], Coulomb
#: friction [N m], armature [kg m^2].
JOINT_PARAMETERS = ("viscous", "coulomb", "armature")


def joint_summaries(ident: Identification) -> dict[str, dict[str, ParameterSummary]]:
    """Each joint's friction and armature (:data:`JOINT_PARAMETERS`); joints with none are left out."""
    theta, std, nominal = ident.theta, ident.estimate.std, ident.params.nominal
    out: dict[str, dict[str, ParameterSummary]] = {}
    for block in ident.params.joints:
        columns = (block.viscous, block.coulomb, block.armature)
        entry = {kind: ParameterSummary(float(nominal[col]), float(theta[col]), float(std[col]),
                                        excitation_status(ident.data, np.eye(ident.params.n)[col]))
                 for kind, col in zip(JOINT_PARAMETERS, columns, strict=True) if col is not None}
        if entry:
            out[block.name] = entry
    return out


class BaseSummary(NamedTuple):
    """One base parameter (a combination the data determine), nominal and identified.

    Attributes:
        expression: The combination, readable (``"link2.m + 11.11 link1.Izz"``).
        coefficients: Parameter name -> coefficient.
        nominal: Its value for the nominal model.
        identified: Its value for the estimate.
        std: Its standard deviation (from the estimate's covariance).
        status: How the data determined it (:func:`excitation_status`).
    """

    expression: str
    coefficients: dict[str, float]
    nominal: float
    identified: float
    std: float
    status: str


def base_summaries(ident: Identification) -> list[BaseSummary]:
    """Each base parameter of the training data, with its value, standard deviation and status."""
    names = ident.params.names
    index = {n: i for i, n in enumerate(names)}
    out = []
    for b in ident.data.base:
        d = np.zeros(len(names))
        for name, c in b.coefficients.items():
            d[index[name]] = c
        std = float(np.sqrt(max(d @ ident.estimate.covariance @ d, 0.0)))
        out.append(BaseSummary(b.expression(), dict(b.coefficients), float(d @ ident.params.nominal),
                               float(d @ ident.theta), std, excitation_status(ident.data, d)))
    return out
