"""What a set of equations can identify: rank, condition number, base parameters, and why not.

Columns are scaled by each parameter's prior standard deviation first, so the singular values
compare parameters of different units on the scale they are uncertain on. With ``W D = U S V^T``:

* rank r: singular values above ``RANK_RTOL`` times the largest; condition number ``s_1 / s_r``.
* a parameter is identifiable on its own iff its unit vector has no component in the null space
  ``V[:, r:]`` (up to ``NULL_TOL``): no change of the others can hide a change of it.
* otherwise it is not excited (its column is zero: no torque in the data depends on it) or it
  enters only in combination with others (the ones sharing its null-space directions).
* excitation of a parameter (or of any combination ``d . theta``): how strongly the data determine
  it, relative to the best-determined direction: the singular value its column would have alone
  after the others took what they can explain, over ``s_1`` (``1 / sqrt(d_s^T (R_s^T R_s)^+ d_s)
  / s_1`` with ``d_s = D d / |D d|``); 0 when it has a null-space component. Below
  ``WEAK_RTOL`` it is *weakly excited*: identifiable in principle, but the log barely moves it, so
  its value leans on small, systematic parts of the torques (and the prior).
* base parameters: a pivoted QR of ``W D`` picks r independent columns; each base parameter is an
  independent parameter plus a combination of the dependent ones (``beta = theta_B + K theta_D``),
  the parameters the data determine (Gautier's base parameters).

The same analysis on random states (structural) tells a parameter that no motion can identify
from one this log did not excite.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from mbctl.robots.identification.regressor import LinearSystem

#: Singular values below this fraction of the largest count as zero.
RANK_RTOL = 1e-7
#: A parameter whose null-space component is below this is identifiable on its own.
NULL_TOL = 1e-4
#: A coefficient of a base-parameter expression below this (relative, scaled) is dropped.
COEFF_TOL = 1e-6
#: A parameter or combination whose excitation (relative singular value) is below this is weakly
#: excited: its effective condition number is above 1 / WEAK_RTOL.
WEAK_RTOL = 1e-2


@dataclass(frozen=True)
class BaseParameter:
    """One base parameter: ``value = sum_j coefficients[name_j] theta_j``.

    Attributes:
        lead: The independent parameter it is built on.
        coefficients: Parameter name -> coefficient (the lead's is 1), in the parameters' units.
    """

    lead: str
    coefficients: dict[str, float]

    def expression(self) -> str:
        """``"a.Izz + 0.09 b.m"``: the combination, readable."""
        parts = [self.lead]
        for name, c in self.coefficients.items():
            if name != self.lead:
                parts.append(f"{'-' if c < 0 else '+'} {abs(c):.4g} {name}")
        return " ".join(parts)

    def value(self, theta: np.ndarray, names: tuple[str, ...]) -> float:
        """Its value for the parameter vector ``theta``."""
        index = {n: i for i, n in enumerate(names)}
        return float(sum(c * theta[index[n]] for n, c in self.coefficients.items()))


@dataclass(frozen=True)
class Identifiability:
    """The identifiability of the parameters from a set of equations.

    Attributes:
        names: Parameter names (n,).
        singular_values: Of the scaled equations, largest first (n,).
        rank: Numerical rank.
        condition_number: Largest over smallest non-zero singular value (scaled columns).
        identifiable: Mask (n,): identifiable on its own.
        excited: Mask (n,): some equation depends on it (its column is not zero).
        partners: Parameter -> the parameters it is confounded with (unidentifiable ones only).
        base: The base parameters.
        scale: The column scale (n,) the analysis used (the prior standard deviations).
        right_vectors: ``V^T`` (n, n) of the scaled equations' SVD (rows: right singular vectors).
    """

    names: tuple[str, ...]
    singular_values: np.ndarray
    rank: int
    condition_number: float
    identifiable: np.ndarray
    excited: np.ndarray
    partners: dict[str, list[str]]
    base: tuple[BaseParameter, ...]
    scale: np.ndarray | None = None
    right_vectors: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Number of parameters."""
        return len(self.names)

    def excitation(self, direction: np.ndarray) -> float:
        """Relative excitation of the combination ``direction . theta`` (see the module docstring).

        1: as well determined as the best direction; 0: not determined by the data (a component in
        the null space, or no data at all).
        """
        if self.rank == 0 or self.right_vectors is None or self.scale is None:
            return 0.0
        d = np.asarray(direction, dtype=float) * self.scale
        norm = float(np.linalg.norm(d))
        if norm == 0.0:
            return 0.0
        w = self.right_vectors @ (d / norm)
        if np.linalg.norm(w[self.rank:]) >= NULL_TOL:
            return 0.0
        S = self.singular_values[:self.rank]
        return float(1.0 / np.sqrt(np.sum((w[:self.rank] / S) ** 2)) / S[0])

    def parameter_excitation(self) -> np.ndarray:
        """Relative excitation (n,) of each parameter alone (0: not identifiable on its own)."""
        return np.array([self.excitation(np.eye(self.n)[i]) for i in range(self.n)])

    def weakly_excited(self) -> np.ndarray:
        """Mask (n,): identifiable on its own but excited below :data:`WEAK_RTOL`."""
        return self.identifiable & (self.parameter_excitation() < WEAK_RTOL)

    def summary(self) -> dict[str, Any]:
        """Rank, condition number and counts, JSON-ready."""
        weak = self.weakly_excited()
        return {"parameters": self.n, "rank": self.rank, "condition_number": self.condition_number,
                "identifiable_alone": int(self.identifiable.sum()),
                "not_excited": int((~self.excited).sum()),
                "weakly_excited": [self.names[i] for i in np.flatnonzero(weak)],
                "weak_excitation_below": WEAK_RTOL}


def analyse(system: LinearSystem, names: tuple[str, ...], scale: np.ndarray) -> Identifiability:
    """Identifiability of the parameters ``names`` from ``system`` (columns scaled by ``scale``).

    Args:
        system: The compressed equations.
        names: Parameter names (n,).
        scale: Positive scale (n,) per parameter (the prior standard deviation).
    """
    Rs = system.R * scale
    n = len(names)
    U, S, Vt = np.linalg.svd(Rs)
    s_max = float(S[0]) if n else 0.0
    rank = int(np.sum(S > RANK_RTOL * s_max)) if s_max > 0 else 0
    cond = float(S[0] / S[rank - 1]) if rank else float("inf")
    null = Vt[rank:].T  # (n, n - rank)
    null_norm = np.linalg.norm(null, axis=1) if null.size else np.zeros(n)
    col = np.linalg.norm(Rs, axis=0)
    excited = col > RANK_RTOL * max(float(col.max()), 1e-300)
    identifiable = null_norm < NULL_TOL
    partners: dict[str, list[str]] = {}
    if null.size:
        overlap = np.abs(null @ null.T)
        for i in np.flatnonzero(~identifiable & excited):
            others = [j for j in np.argsort(-overlap[i])
                      if j != i and overlap[i, j] > NULL_TOL and excited[j]]
            partners[names[i]] = [names[j] for j in others[:4]]
    base = _base_parameters(Rs, rank, names, scale) if rank else ()
    return Identifiability(tuple(names), S, rank, cond, identifiable, excited, partners, base,
                           np.asarray(scale, dtype=float).copy(), Vt)


def _base_parameters(Rs: np.ndarray, rank: int, names: tuple[str, ...], scale: np.ndarray
                     ) -> tuple[BaseParameter, ...]:
    """Gautier's base parameters from a pivoted QR of the scaled equations."""
    _, Rq, piv = scipy.linalg.qr(Rs, pivoting=True, mode="economic")
    ind, dep = piv[:rank], piv[rank:]
    K = scipy.linalg.solve_triangular(Rq[:rank, :rank], Rq[:rank, rank:]) if len(dep) else np.zeros((rank, 0))
    out = []
    for i, lead in enumerate(ind):
        coefficients = {names[lead]: 1.0}
        for j, d in enumerate(dep):
            c = K[i, j]
            if abs(c) > COEFF_TOL:
                # beta_s = theta_s[lead] + K theta_s[dep]; back to units of theta[lead]
                coefficients[names[d]] = float(c * scale[lead] / scale[d])
        out.append(BaseParameter(names[lead], coefficients))
    return tuple(out)


def reasons(data: Identifiability, structural: Identifiability | None) -> dict[str, str]:
    """Why each parameter the data cannot identify on its own is not identified (name -> reason)."""
    out = {}
    for i, name in enumerate(data.names):
        if data.identifiable[i]:
            continue
        structurally = structural is not None and not structural.identifiable[i]
        never = structural is not None and not structural.excited[i]
        if never:
            why = ("no joint torque of this robot depends on it in any motion (e.g. an inertia about "
                   "an axis its joints never turn); kept at its prior")
        elif not data.excited[i]:
            why = ("no torque in this log depends on it: the log does not move what it acts on; "
                   "excite that motion, kept at its prior")
        else:
            with_ = ", ".join(data.partners.get(name, [])) or "others"
            why = f"enters only in combination with {with_}"
            why += (" in every motion (structural: only the combination is a base parameter)"
                    if structurally else " in this log (another motion would separate them)")
            why += "; the prior decides the split"
        out[name] = why
    return out
