"""Pass criteria of the cross-check: one ``Tolerance`` per compared quantity, and why.

A quantity passes when ``rel = abs / max(scale, floor) <= rtol``, where ``abs`` is the largest
absolute difference between Pinocchio and MuJoCo over all states and entries and ``scale`` the
largest MuJoCo magnitude (see ``mbctl.robots.crosscheck.evaluate``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from mbctl.robots.crosscheck.exceptions import CrossCheckError


@dataclass(frozen=True)
class Tolerance:
    """Pass criterion of one quantity: ``rel = abs / max(scale, floor) <= rtol``.

    Attributes:
        rtol: Largest passing relative error [-].
        floor: Magnitude [unit] below which the quantity counts as zero.
        unit: SI unit of the quantity.
        description: What is compared, with the frame.
        method: How each engine's value is computed, where it is not simply the engine's own
            function of that name ("" otherwise); printed in the report under the quantity.
    """

    rtol: float
    floor: float
    unit: str
    description: str
    method: str = ""

    def __post_init__(self) -> None:
        """Reject non-positive or non-finite tolerances."""
        for name in ("rtol", "floor"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise CrossCheckError(f"Tolerance.{name} must be a positive finite number; got {value!r}")


#: Relative tolerance of every quantity [-]. Both engines evaluate the same closed-form rigid-body
#: expressions in double precision; measured agreement is 1e-16 .. 1e-13 relative (the G1 and
#: the 2-link arm, see the tests). 1e-9 leaves a margin of 1e4 for round-off growth (forward
#: dynamics loses ~cond(M) * eps; a mass matrix with cond(M) = 1e6 still passes), while any
#: physical modelling difference worth having (a 1e-6 relative change of a mass, a 1 um shift
#: of an inertial frame) still fails.
RTOL = 1e-9

#: The floors are magnitudes below which a quantity is "zero" for a robot of any size we support
#: (a 0.1 kg finger to a 100 kg humanoid). They matter only when a quantity vanishes in every
#: state (gravity and potential energy with gravity off, the Jacobians of a body welded to the
#: world); then ``rel = abs / floor`` and the absolute error must stay below ``RTOL * floor``,
#: e.g. 1e-12 N m for gravity torques, still 1e3 above round-off of a zero quantity.
TOLERANCES: Mapping[str, Tolerance] = MappingProxyType(
    {
        # Rotation matrices have entries of magnitude 1 (every row has unit norm): floor 1.
        "fk_position": Tolerance(RTOL, 1e-3, "m", "p_WF of every body and site, world frame"),
        "fk_rotation": Tolerance(RTOL, 1.0, "-", "R_WF of every body and site"),
        "jacobian_linear": Tolerance(
            RTOL, 1e-3, "m/rad", "J_WF linear rows, LOCAL_WORLD_ALIGNED, every body and site"
        ),
        "jacobian_angular": Tolerance(
            RTOL, 1.0, "-", "J_WF angular rows, LOCAL_WORLD_ALIGNED, every body and site"
        ),
        "com": Tolerance(RTOL, 1e-3, "m", "p_WC, centre of mass of the moving bodies, world frame"),
        "com_jacobian": Tolerance(RTOL, 1e-3, "m/rad", "J_WC, world frame"),
        # 1e-6 kg m^2: inertia of a 10 g, 1 cm body; armatures are larger.
        "mass_matrix": Tolerance(RTOL, 1e-6, "kg m^2", "M(q) with armature"),
        "gravity": Tolerance(RTOL, 1e-3, "N m", "g(q), generalized gravity force"),
        "bias": Tolerance(RTOL, 1e-3, "N m", "b(q, v) = C(q, v) v + g(q)"),
        "forward_dynamics": Tolerance(RTOL, 1e-3, "rad/s^2", "a = FD(q, v, tau): ABA vs qacc"),
        "inverse_dynamics": Tolerance(RTOL, 1e-3, "N m", "tau = ID(q, v, a): RNEA vs mj_inverse"),
        "kinetic_energy": Tolerance(
            RTOL,
            1e-6,
            "J",
            "kinetic energy 1/2 v^T M v, armature included",
            "Pinocchio: computeKineticEnergy of the rigid bodies + 1/2 v^T diag(armature) v; "
            "MuJoCo: energy[1] = 1/2 v^T M v, armature in M",
        ),
        "potential_energy": Tolerance(RTOL, 1e-6, "J", "gravitational energy of the moving bodies"),
        "momentum_linear": Tolerance(RTOL, 1e-6, "kg m/s", "centroidal linear momentum, world axes"),
        "momentum_angular": Tolerance(
            RTOL, 1e-6, "kg m^2/s", "centroidal angular momentum about the CoM, world axes"
        ),
    }
)
