"""PD gains as a frozen, validated value, derived from natural frequency, damping ratio and inertia.

For a joint of inertia ``I`` [kg m^2] under ``tau = kp e + kd de``, the closed loop
``I de'' + kd de' + kp e = 0`` has natural frequency ``omega`` and damping ratio ``zeta`` when::

    kp = I omega^2            [N m/rad]
    kd = 2 zeta I omega       [N m s/rad]

For computed torque the inertia is already cancelled by ``M(q)``, so the gains are per unit
inertia (``inertia=1``): ``kp = omega^2`` [1/s^2] and ``kd = 2 zeta omega`` [1/s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mbctl.control.exceptions import GainsError


def _vector(name: str, value: npt.ArrayLike, n: int | None = None) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float, ndmin=1)
    except (TypeError, ValueError) as exc:
        raise GainsError(f"{name} must be a numeric vector; got {value!r}") from exc
    if arr.ndim != 1:
        raise GainsError(f"{name} must be a vector (one value per joint); got shape {arr.shape}")
    if n is not None and arr.size == 1 and n != 1:
        arr = np.full(n, float(arr[0]))
    if n is not None and arr.size != n:
        raise GainsError(f"{name} must have {n} values (one per joint); got {arr.size}")
    bad = np.flatnonzero(~np.isfinite(arr) | (arr < 0))
    if bad.size:
        raise GainsError(
            f"{name} must be finite and >= 0; got {arr[bad].tolist()} at joint indices {bad.tolist()}"
        )
    return arr


@dataclass(frozen=True)
class PDGains:
    """Proportional and derivative gains, one pair per controlled joint (read-only arrays).

    ``tau = kp * (q_ref - q) + kd * (v_ref - v)`` elementwise.

    Attributes:
        kp: Stiffness (n,) [N m/rad] (or [1/s^2] per unit inertia for computed torque).
        kd: Damping (n,) [N m s/rad] (or [1/s] per unit inertia for computed torque).

    Raises:
        GainsError: Different lengths, a non-finite or a negative gain, or an empty vector.
    """

    kp: np.ndarray
    kd: np.ndarray

    def __post_init__(self) -> None:
        kp = _vector("kp", self.kp)
        kd = _vector("kd", self.kd)
        if kp.size == 0:
            raise GainsError("kp must have at least one value; got an empty vector")
        if kp.size != kd.size:
            raise GainsError(
                f"kp and kd must have the same length (one per joint); got {kp.size} and {kd.size}"
            )
        kp.setflags(write=False)
        kd.setflags(write=False)
        object.__setattr__(self, "kp", kp)
        object.__setattr__(self, "kd", kd)

    @property
    def size(self) -> int:
        """Number of joints the gains cover."""
        return int(self.kp.size)

    def broadcast(self, n: int) -> PDGains:
        """These gains for ``n`` joints: a single pair is repeated, otherwise the size must be n.

        Raises:
            GainsError: Neither one pair nor n pairs.
        """
        if self.size == n:
            return self
        if self.size == 1:
            return PDGains(np.full(n, self.kp[0]), np.full(n, self.kd[0]))
        raise GainsError(f"gains cover {self.size} joints; the controller has {n} joints")


def gains_from_frequency(
    omega_rad_s: npt.ArrayLike, zeta: npt.ArrayLike = 1.0, inertia: npt.ArrayLike = 1.0
) -> PDGains:
    """``kp = inertia omega^2``, ``kd = 2 zeta inertia omega``, elementwise (scalars broadcast).

    Args:
        omega_rad_s: Closed-loop natural frequency [rad/s], scalar or (n,); > 0.
        zeta: Damping ratio [-], scalar or (n,); >= 0 (1 is critical damping).
        inertia: Joint inertia [kg m^2] (or [kg]), scalar or (n,); > 0. Use 1 for computed
            torque, whose loop is already normalised by ``M(q)``.

    Returns:
        PDGains of the broadcast length.

    Raises:
        GainsError: A non-positive frequency or inertia, a negative damping ratio, non-finite
            values, or lengths that do not broadcast.
    """
    try:
        omega, z, inertia_arr = np.broadcast_arrays(
            np.atleast_1d(np.asarray(omega_rad_s, dtype=float)),
            np.atleast_1d(np.asarray(zeta, dtype=float)),
            np.atleast_1d(np.asarray(inertia, dtype=float)),
        )
    except (TypeError, ValueError) as exc:
        raise GainsError(
            f"omega_rad_s, zeta and inertia must be numbers or vectors of one length; got "
            f"{omega_rad_s!r}, {zeta!r}, {inertia!r}"
        ) from exc
    for name, arr, strict in (("omega_rad_s", omega, True), ("zeta", z, False),
                              ("inertia", inertia_arr, True)):
        bad = np.flatnonzero(~np.isfinite(arr) | ((arr <= 0) if strict else (arr < 0)))
        if bad.size:
            bound = "> 0" if strict else ">= 0"
            raise GainsError(
                f"{name} must be finite and {bound}; got {arr[bad].tolist()} at indices {bad.tolist()}"
            )
    return PDGains(inertia_arr * omega**2, 2.0 * z * inertia_arr * omega)
