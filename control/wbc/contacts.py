"""Foot contacts for whole-body inverse dynamics, read from the model's collision geoms.

A foot touches the ground through contact *points*: the lowest points of its collision geoms
(MuJoCo point contacts, condim 3, e.g. the Menagerie G1's four sole spheres). Each point carries a
force ``f`` (3,) [N] in the foot frame F, whose z is the sole's normal (the friction pyramid is
about it, as in TSID's 6-D contact); the foot's wrench, centre of pressure and friction follow
from them. A point's velocity is ``G_P v_F`` with the foot's LOCAL twist ``v_F = J_F v`` and the
constant ``G_P = [I, -[p_FP]x]``, so the points' Jacobian is one product ``G_F J_F``. With the
corners of the sole as points and ``f_z >= 0``, the centre of pressure stays inside the sole
rectangle by construction (it is a convex combination of the points), so no separate CoP
constraint is needed.

A foot's contact switches with a force ramp (:class:`ContactState`): its weight ``w_c`` goes from
1 to 0 (release) or 0 to 1 (touch-down) over ``ramp_s`` of the state's time, while its
acceleration constraint stays; a released foot's constraint is removed when its weight reaches 0.

Notation: W world, F the foot frame (a Pinocchio frame: the foot site), P a contact point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import WBCSetupError
from mbctl.robots.model_pair import Robot

#: A ramp's weight within this of its target is its target [-]: the steps' rounding leaves a residue
#: (25 steps of 0.04 from 1 end at 1.1e-13), and a foot at such a weight has force bounds of
#: [1e-13, 4e-11] N, not pinned at zero: a degenerate QP that daqp reported infeasible (then the
#: controller's fallback: a fall) after pushes while walking.
RAMP_SNAP = 1e-9


@dataclass(frozen=True)
class FootContact:
    """A foot's contact points in its frame F, and its friction.

    Attributes:
        name: Label (the frame name by default).
        frame: Pinocchio frame of the foot (a site or body frame).
        points_F: Contact points p_FP (n, 3) [m] in F (read-only).
        mu: Coulomb friction coefficient [-] of the foot geoms.
        geoms: MuJoCo geom ids of the contact geoms (for measuring the plant's forces).
    """

    name: str
    frame: str
    points_F: np.ndarray
    mu: float
    geoms: tuple[int, ...]

    def __post_init__(self) -> None:
        pts = np.array(self.points_F, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 1 or not np.all(np.isfinite(pts)):
            raise WBCSetupError(f"contact {self.name!r}: points_F must be a finite (n, 3) array; got "
                                f"{np.asarray(self.points_F).tolist()!r}")
        if not (np.isfinite(self.mu) and self.mu > 0):
            raise WBCSetupError(f"contact {self.name!r}: friction mu must be > 0; got {self.mu}")
        pts.setflags(write=False)
        object.__setattr__(self, "points_F", pts)

    @property
    def n_points(self) -> int:
        """Number of contact points."""
        return len(self.points_F)

    @property
    def sole_x_m(self) -> tuple[float, float]:
        """(min, max) of the points along F's x [m]."""
        return float(self.points_F[:, 0].min()), float(self.points_F[:, 0].max())

    @property
    def sole_y_m(self) -> tuple[float, float]:
        """(min, max) of the points along F's y [m]."""
        return float(self.points_F[:, 1].min()), float(self.points_F[:, 1].max())


def foot_contact_from_model(robot: Robot, frame: str, body: str | None = None) -> FootContact:
    """The contact points of a foot: the bottom of each collision sphere (or box corner) of ``body``.

    Args:
        robot: The robot (its compiled MuJoCo model is read, not changed).
        frame: The Pinocchio frame the points are expressed in (e.g. the foot site).
        body: The MuJoCo body whose geoms touch the ground (default: the frame's parent body,
            read from the Pinocchio model).

    Raises:
        WBCSetupError: No colliding sphere or box geom on the body, or an unknown frame/body.
    """
    pm, m = robot.pin_model, robot.mj_model
    if not pm.existFrame(frame):
        raise WBCSetupError(f"unknown foot frame {frame!r}")
    fid = pm.getFrameId(frame)
    if body is None:
        body = pm.frames[pm.frames[fid].parentFrame].name
    bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0 or not pm.existFrame(body):
        raise WBCSetupError(f"unknown foot body {body!r} for contact frame {frame!r}")
    # X_FB from Pinocchio's frames (every body and site is a frame); MuJoCo geoms are in B
    pdata = pm.createData()
    pin.framesForwardKinematics(pm, pdata, pin.neutral(pm))
    X_FB = pdata.oMf[fid].inverse() * pdata.oMf[pm.getFrameId(body)]
    points: list[np.ndarray] = []
    geoms: list[int] = []
    mus: list[float] = []
    for g in range(m.ngeom):
        if m.geom_bodyid[g] != bid or (m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0):
            continue
        p_Bg, size = m.geom_pos[g], m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
            # the sphere's lowest point when the foot is flat (F's -z is down)
            p_Fg = X_FB.act(p_Bg)
            points.append(p_Fg - np.array([0.0, 0.0, size[0]]))
        elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            R_Bg = np.empty(9)
            mujoco.mju_quat2Mat(R_Bg, m.geom_quat[g])
            for sx in (-1, 1):
                for sy in (-1, 1):
                    corner_B = p_Bg + R_Bg.reshape(3, 3) @ (np.array([sx, sy, -1.0]) * size)
                    points.append(X_FB.act(corner_B))
        else:
            continue
        geoms.append(g)
        mus.append(float(m.geom_friction[g][0]))
    if not points:
        raise WBCSetupError(f"body {body!r} has no colliding sphere or box geom to stand on")
    return FootContact(frame, frame, np.array(points), min(mus), tuple(geoms))


@dataclass
class ContactState:
    """One foot in the whole-body QP: its force variables, its ramp and where it was put down.

    Attributes:
        contact: The foot's contact points and friction.
        fid: Pinocchio frame id of the foot frame.
        cols: The foot's force variables in the QP's x.
        fz: The normal-force variables among them (a strided slice of x).
        active: The foot-acceleration equality is in force.
        weight: Force ramp ``w_c`` in [0, 1] (scales the normal-force bounds).
        target_weight: Where the ramp goes (0: release, 1: load).
        X_WF0: The foot's pose when it was put down (its slip feedback holds it there).
        G_F: (3 n_points, 6) the points' velocities in F from the foot's LOCAL twist (constant).
    """

    contact: FootContact
    fid: int
    cols: slice
    fz: slice
    active: bool = True
    weight: float = 1.0
    target_weight: float = 1.0
    X_WF0: pin.SE3 = field(default_factory=pin.SE3.Identity)
    #: (3 n_points, 6) the points' velocities in F from the foot's LOCAL twist: rows [I, -[p_FP]x].
    G_F: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        pts = self.contact.points_F
        G = np.zeros((len(pts), 3, 6))
        G[:, :, :3] = np.eye(3)
        for i, p in enumerate(pts):  # v_P = v + w x p = v - [p]x w
            G[i, :, 3:] = -pin.skew(p)
        self.G_F = G.reshape(-1, 6)

    def hold(self, X_WF: pin.SE3) -> None:
        """In contact at full weight, held at ``X_WF``."""
        self.active, self.weight, self.target_weight, self.X_WF0 = True, 1.0, 1.0, X_WF

    def touch_down(self, X_WF: pin.SE3) -> None:
        """Constrained at ``X_WF`` from now on, its force ramping up from zero."""
        self.active, self.target_weight, self.X_WF0 = True, 1.0, X_WF
        self.weight = min(self.weight, 0.0)

    def advance_ramp(self, dt_s: float, ramp_s: float) -> None:
        """Move the weight toward its target by ``dt_s / ramp_s``; free the foot when it reaches 0."""
        if self.weight == self.target_weight and (self.active or self.target_weight != 0.0):
            return
        step = dt_s / ramp_s
        if self.weight < self.target_weight:
            self.weight = min(self.target_weight, self.weight + step)
        elif self.weight > self.target_weight:
            self.weight = max(self.target_weight, self.weight - step)
        if abs(self.weight - self.target_weight) < RAMP_SNAP:
            self.weight = self.target_weight
        if self.target_weight == 0.0 and self.weight == 0.0:
            self.active = False
