"""The stacked identification equations ``W theta = y`` of a set of samples, and torque predictions.

Per sample, Pinocchio's joint-torque regressor gives ``M(q) a + b(q, v) = Y(q, v, a) pi`` for the
joints' parameters; :class:`~mbctl.robots.identification.parameters.ParameterSet` turns it into the
identified columns and the known rest, so ``W_k theta = S^T tau_k - known_k (+ J_c^T f_k)``.

Contacts (a robot on its feet), per sample, with ``J_c`` the stacked 6-row Jacobians of the
contact bodies touching the ground:

``"projected"`` (joint torques only, no force sensor): the rows are projected onto the null space
    of ``J_c^T``, ``P = N^T`` with N an orthonormal basis of ``ker(J_c)`` (from a complete QR of
    ``J_c^T``), so ``P J_c^T f = 0`` for any contact wrench: ``P W_k theta = P (S^T tau_k - known)``.
    With both feet down the G1 keeps 35 - 12 = 23 equations per sample.
``"measured"`` (the log has the wrenches): ``J_c^T f_k`` is added to the right-hand side, every
    row kept.
A fixed-base robot has no contact rows.

The equations are not kept: they are folded into the triangular factor of ``[W | y]`` block by
block (Householder QR), so memory does not grow with the log, and ``|W theta - y|^2 = |R theta -
z|^2 + rho^2`` for any theta.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.robots.identification.exceptions import IdentificationError
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.samples import Samples

#: How the contact forces of a robot on its feet enter the equations.
CONTACT_MODES = ("projected", "measured")
#: Rows folded into the triangular factor at a time.
BLOCK_ROWS = 4000


@dataclass(frozen=True)
class LinearSystem:
    """``|W theta - y|^2 = |R theta - z|^2 + rho2``: the stacked equations, compressed.

    Attributes:
        R: Upper triangular (n, n).
        z: (n,).
        rho2: Squared residual no theta can remove.
        rows: Number of equations folded in.
        y_sq: ``|y|^2`` (for relative residuals).
    """

    R: np.ndarray
    z: np.ndarray
    rho2: float
    rows: int
    y_sq: float

    def residual_sq(self, theta: np.ndarray) -> float:
        """``|W theta - y|^2``."""
        r = self.R @ theta - self.z
        return float(r @ r + self.rho2)


class _Accumulator:
    """Householder QR of ``[W | y]`` fed block by block."""

    def __init__(self, n: int):
        self.R = np.zeros((0, n + 1))
        self.buffer: list[np.ndarray] = []
        self.buffered = 0
        self.rows = 0
        self.y_sq = 0.0
        self.n = n

    def add(self, W: np.ndarray, y: np.ndarray) -> None:
        self.buffer.append(np.hstack([W, y[:, None]]))
        self.buffered += len(y)
        self.rows += len(y)
        self.y_sq += float(y @ y)
        if self.buffered >= BLOCK_ROWS:
            self._fold()

    def _fold(self) -> None:
        if self.buffer:
            stacked = np.vstack([self.R, *self.buffer])
            self.R = np.asarray(np.linalg.qr(stacked, mode="r"))
            self.buffer, self.buffered = [], 0

    def system(self) -> LinearSystem:
        self._fold()
        n = self.n
        R_aug = np.zeros((n + 1, n + 1))
        R_aug[:len(self.R)] = self.R[:n + 1]
        return LinearSystem(R_aug[:n, :n].copy(), R_aug[:n, n].copy(), float(R_aug[n, n] ** 2), self.rows,
                            self.y_sq)


def _check_mode(samples: Samples, contact: str) -> None:
    if contact not in CONTACT_MODES:
        raise IdentificationError(f"contact mode {contact!r} is unknown; choose one of "
                                  f"{', '.join(CONTACT_MODES)}")
    if contact == "measured" and samples.contacts.shape[1] and samples.wrenches is None:
        raise IdentificationError("contact mode 'measured' needs measured contact wrenches, and the log "
                                  "has none (a log recorded over DDS has none: the G1 has no foot force "
                                  "sensors); use 'projected' (joint torques only)")


class SampleEquations:
    """Iterates a set of samples' equations: (W_k, y_k, P_k) per sample, before projection.

    ``W_k theta = y_k`` holds up to the contact wrench; P_k (r, nv) removes it (projected mode),
    or is None when every row is kept (a fixed base, no contact, or measured wrenches, which are
    already added to y_k).

    Args:
        params: The parameter set.
        samples: The samples.
        contact: "projected" or "measured" (see the module docstring).
    """

    def __init__(self, params: ParameterSet, samples: Samples, contact: str = "projected"):
        _check_mode(samples, contact)
        self.params = params
        self.samples = samples
        self.contact = contact
        model = params.model
        self.data = model.createData()
        self.frames = [model.getFrameId(b, pin.FrameType.BODY) for b in samples.contact_bodies]

    def __iter__(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
        """Per sample: W (nv, n), y (nv,) and the projector P (r, nv) or None."""
        params, s = self.params, self.samples
        model, data = params.model, self.data
        for k in range(len(s)):
            q, v, a = s.q[k], s.v[k], s.a[k]
            # (nv, 10 (njoints - 1)); Pinocchio returns a vector when nv = 1
            Y = np.reshape(pin.computeJointTorqueRegressor(model, data, q, v, a), (model.nv, -1))
            W = params.columns(Y, v, a)
            y = s.tau[k] - params.known(Y, v, a)
            on = s.contacts[k]
            if not on.any():
                yield W, y, None
                continue
            pin.computeJointJacobians(model, data, q)
            if self.contact == "measured":
                for c in np.flatnonzero(on):
                    J = pin.getFrameJacobian(model, data, self.frames[c], pin.LOCAL_WORLD_ALIGNED)
                    y += J.T @ s.wrenches[k, c]  # type: ignore[index]
                yield W, y, None
                continue
            Jc = np.vstack([pin.getFrameJacobian(model, data, self.frames[c], pin.LOCAL)
                            for c in np.flatnonzero(on)])
            Q, _ = np.linalg.qr(Jc.T, mode="complete")
            yield W, y, Q[:, np.linalg.matrix_rank(Jc):].T


def stack(params: ParameterSet, samples: Samples, contact: str = "projected") -> LinearSystem:
    """The compressed equations of ``samples`` (see :class:`LinearSystem`)."""
    acc = _Accumulator(params.n)
    for W, y, P in SampleEquations(params, samples, contact):
        if P is None:
            acc.add(W, y)
        else:
            acc.add(P @ W, P @ y)
    return acc.system()


@dataclass(frozen=True)
class TorquePrediction:
    """Joint torques measured and predicted by a parameter vector, on a set of samples.

    Attributes:
        t_s: Times (M,) [s].
        joints: The actuated joints (k,).
        measured: Measured torques (M, k) [N m].
        predicted: Predicted torques (M, k) [N m]: the model's inverse dynamics with the contact
            wrench eliminated the same way as in identification (projected: the torques left
            after the best-fitting contact wrench; measured: with the measured wrench).
    """

    t_s: np.ndarray
    joints: tuple[str, ...]
    measured: np.ndarray
    predicted: np.ndarray

    def rmse(self) -> float:
        """RMS of the torque error over every joint and sample [N m]."""
        return float(np.sqrt(np.mean((self.measured - self.predicted) ** 2)))

    def rmse_by_joint(self) -> dict[str, float]:
        """RMS torque error per joint [N m]."""
        err = np.sqrt(np.mean((self.measured - self.predicted) ** 2, axis=0))
        return dict(zip(self.joints, err.tolist(), strict=True))


def predict(params: ParameterSet, thetas: list[np.ndarray], samples: Samples, joints: tuple[str, ...],
            contact: str = "projected") -> list[TorquePrediction]:
    """The torques each of ``thetas`` predicts at ``samples`` for ``joints``.

    The residual of the balance ``r = y - W theta`` is what the model does not explain; with
    projected contacts only its part no contact wrench can explain counts (``P^T P r``). The
    prediction is the measured torque minus that residual, at the joints' v indices.
    """
    model = params.model
    idx = [model.joints[model.getJointId(j)].idx_v for j in joints]
    measured = samples.tau[:, idx]
    predicted = [np.empty_like(measured) for _ in thetas]
    for k, (W, y, P) in enumerate(SampleEquations(params, samples, contact)):
        for out, theta in zip(predicted, thetas, strict=True):
            r = y - W @ theta
            if P is not None:
                r = P.T @ (P @ r)
            out[k] = measured[k] - r[idx]
    return [TorquePrediction(samples.t_s, tuple(joints), measured, p) for p in predicted]
