"""Excitation trajectories for identification: a Fourier series optimised for the regressor.

The identification equations at N samples of a trajectory stack into ``W`` (the joint-torque
regressor's columns for the parameters of the bodies the joints move, scaled by the prior's
standard deviations). A trajectory is exciting when W is well conditioned: every identifiable
combination of parameters moves the torques by a comparable amount, so torque noise does not
swamp any of them. :func:`design_excitation` minimises ``log cond(W)`` (over its structural rank,
what any motion could reach) over the coefficients of a :class:`FourierTrajectory`, subject to

* the joint limits (with a margin), at every sample (and checked again on a finer grid),
* a speed limit per joint,
* the nominal model's inverse-dynamics torque within a fraction of each actuator's limit,
* a clearance between the robot's own collision geoms (:data:`SELF_CLEARANCE_M`, every pair
  ``robot:robot`` of :mod:`mbctl.robots.collision` that is not already that close at the start),
  so the arm does not hit itself: a contact is a force the identification cannot explain, and its
  rows are dropped,

with SLSQP (``scipy.optimize.minimize``, finite-difference gradients). The start is random
(seeded) and shrunk into the limits, so a failed optimisation still returns a feasible motion.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.planners.exceptions import InvalidPlanningInput
from mbctl.planners.fourier import FourierTrajectory, rest_projection
from mbctl.robots.collision import CollisionPair, GeomPairs, pair_distances, resolve_pairs
from mbctl.robots.exceptions import CollisionPairError
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.threads import single_threaded_blas
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_kinematics import PlantKinematics

#: Singular values of the scaled regressor below this fraction of the largest count as zero.
RANK_RTOL = 1e-7
#: Torque limit [N m] assumed for a joint whose actuator and model give none.
DEFAULT_EFFORT_N_M = 10.0
#: Distance [m] every pair of the robot's own collision geoms keeps along an excitation.
SELF_CLEARANCE_M = 0.01
#: Distance [m] over which a clearance constraint is normalised (and farther pairs are not measured).
CLEARANCE_SCALE_M = 0.1
#: Most harmonics per joint a design takes. The design has 2 x joints x harmonics coefficients and
#: finite-difference gradients, so its time grows with their square, while more harmonics stop
#: lowering the condition number: the 2-link arm (period 5 s, 80 samples) reaches 58.8 with 5
#: harmonics in 2.8 s, 56.0 with 10 in 10.6 s and 63.1 with 20 in 20 s.
MAX_HARMONICS = 10
#: Design samples per period of the highest harmonic, at least (the grid must resolve it).
SAMPLES_PER_HARMONIC = 4


@dataclass(frozen=True)
class ExcitationLimits:
    """Bounds an excitation respects, per excited joint.

    Attributes:
        q_min: Lowest position (n,) [rad].
        q_max: Highest position (n,) [rad].
        v_max: Largest speed (n,) [rad/s].
        tau_max: Largest inverse-dynamics torque (n,) [N m] of the nominal model.
        defaulted_effort: Joints whose torque limit is :data:`DEFAULT_EFFORT_N_M` because neither
            the model nor the actuator gives one (say so to the user).
    """

    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    tau_max: np.ndarray
    defaulted_effort: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.q_min)
        for name in ("q_min", "q_max", "v_max", "tau_max"):
            arr = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if arr.shape != (n,) or not np.all(np.isfinite(arr)):
                raise InvalidPlanningInput(f"ExcitationLimits.{name} must be {n} finite numbers; got {arr}")
            object.__setattr__(self, name, arr)
        bad = np.flatnonzero(self.q_max <= self.q_min)
        if bad.size:
            raise InvalidPlanningInput(f"ExcitationLimits: q_max <= q_min at joint index {int(bad[0])} "
                                       f"({self.q_max[bad[0]]} <= {self.q_min[bad[0]]} rad)")
        for name in ("v_max", "tau_max"):
            arr = getattr(self, name)
            bad = np.flatnonzero(arr <= 0)
            if bad.size:
                raise InvalidPlanningInput(f"ExcitationLimits.{name} must be > 0; joint index {int(bad[0])} "
                                           f"has {arr[bad[0]]}")

    @classmethod
    def from_robot(cls, robot: Robot, joints: Sequence[str], q_start: npt.ArrayLike, *,
                   range_rad: float = 1.2, margin_rad: float = 0.05, v_max_rad_s: float = 3.0,
                   torque_fraction: float = 0.5) -> ExcitationLimits:
        """Limits from the model.

        The joint range (within ``range_rad`` of the start for unlimited joints, ``margin_rad``
        inside finite limits), ``v_max_rad_s``, and ``torque_fraction`` of each joint's torque
        limit (the smallest of the model's effort limit, the actuator's force range and a motor's
        ctrl range; none: :data:`DEFAULT_EFFORT_N_M`).

        Raises:
            InvalidPlanningInput: A joint whose range is no wider than the two margins, or whose
                start lies outside its range less the margins (names the joint, its range, the
                margins and the start).
        """
        model = robot.pin_model
        q0 = np.asarray(q_start, dtype=float)
        lo, hi, v, tau = [], [], [], []
        defaulted = []
        for j in joints:
            layout = robot.joint(j)
            i = layout.idx_q
            lower, upper = float(model.lowerPositionLimit[i]), float(model.upperPositionLimit[i])
            low = lower + margin_rad if np.isfinite(lower) and lower > -1e6 else q0[i] - range_rad
            high = upper - margin_rad if np.isfinite(upper) and upper < 1e6 else q0[i] + range_rad
            if high <= low:
                raise InvalidPlanningInput(
                    f"joint {j!r} has the range [{lower:g}, {upper:g}] rad ({upper - lower:g} rad wide); the "
                    f"excitation keeps {margin_rad:g} rad inside each limit, so it needs a range wider than "
                    f"{2 * margin_rad:g} rad: widen the joint's range in the model or leave the joint out")
            if not low <= q0[i] <= high:
                raise InvalidPlanningInput(
                    f"joint {j!r} starts at {q0[i]:g} rad, outside its range [{lower:g}, {upper:g}] rad less "
                    f"the excitation's {margin_rad:g} rad margins ([{low:g}, {high:g}] rad): start it inside")
            lo.append(max(low, q0[i] - range_rad))
            hi.append(min(high, q0[i] + range_rad))
            v.append(v_max_rad_s)
            info = robot.actuator_for_joint(j)
            candidates = [float(model.effortLimit[layout.idx_v]), min(abs(x) for x in info.force_range)]
            if info.kind == "torque":  # a motor's ctrl is its torque (times the gear)
                candidates.append(min(abs(x) for x in info.ctrl_range) * abs(info.gear))
            finite = [c for c in candidates if np.isfinite(c) and c > 0]
            tau.append(torque_fraction * (min(finite) if finite else DEFAULT_EFFORT_N_M))
            if not finite:
                defaulted.append(j)
        return cls(np.array(lo), np.array(hi), np.array(v), np.array(tau), tuple(defaulted))


@dataclass(frozen=True)
class ExcitationDesign:
    """An optimised excitation.

    Attributes:
        trajectory: The Fourier trajectory.
        condition_number: cond(W) of the scaled regressor at the design samples.
        initial_condition_number: The same for the random start.
        structural_rank: Rank any motion of these joints reaches (the cond is over it).
        iterations: SLSQP iterations.
        limit_use: Largest fraction of each limit used: q range, speed, torque (3,).
        limits: The limits the design kept.
        self_pairs: Labels of the robot's own geom pairs kept :data:`SELF_CLEARANCE_M` apart
            (empty: the robot has none that can touch).
        min_clearance_m: Smallest distance of those pairs along the design [m] (None: no pairs;
            at most :data:`CLEARANCE_SCALE_M`, farther is not measured).
    """

    trajectory: FourierTrajectory
    condition_number: float
    initial_condition_number: float
    structural_rank: int
    iterations: int
    limit_use: np.ndarray
    limits: ExcitationLimits | None = None
    self_pairs: tuple[str, ...] = ()
    min_clearance_m: float | None = None


class _Evaluator:
    """The scaled regressor, limits and torques of a trajectory at the design samples (cached per x)."""

    def __init__(self, robot: Robot, joints: tuple[str, ...], q_full: np.ndarray, params: ParameterSet,
                 limits: ExcitationLimits, period_s: float, harmonics: int, n_samples: int,
                 self_clearance: bool = True):
        self.robot, self.joints, self.params, self.limits = robot, joints, params, limits
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.q_full = q_full
        self.iq = np.array([robot.joint(j).idx_q for j in joints])
        self.iv = np.array([robot.joint(j).idx_v for j in joints])
        self.scale = params.prior_std()
        self.period_s, self.L = period_s, harmonics
        self.t = np.linspace(0.0, period_s, n_samples, endpoint=False)
        self.P_a, self.P_b = rest_projection(harmonics)
        self.rank = self._structural_rank()
        self._cache: dict[bytes, tuple[float, np.ndarray]] = {}
        self.pairs = (_self_pairs(robot, q_full, joints) if self_clearance
                      else GeomPairs(np.zeros((0, 2), dtype=int), ()))
        self._kinematics = PlantKinematics(robot=robot) if len(self.pairs) else None

    def clearance(self, q: np.ndarray) -> np.ndarray:
        """Smallest distance [m] of each self pair (P,) over the joint positions ``q`` (N, n)."""
        if self._kinematics is None:
            return np.zeros(0)
        qf = self.q_full.copy()
        out = np.full(len(self.pairs), CLEARANCE_SCALE_M)
        m = self.robot.mj_model
        for row in q:
            qf[self.iq] = row
            d = self._kinematics.at(qf)
            out = np.minimum(out, pair_distances(m, d, self.pairs.ids, CLEARANCE_SCALE_M))
        return out

    def trajectory(self, x: np.ndarray) -> FourierTrajectory:
        n, L = len(self.joints), self.L
        ab = x.reshape(2, n, L)
        return FourierTrajectory.from_free(self.joints, self.q_full[self.iq], self.period_s, ab[0], ab[1])

    def _stack(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        rows = []
        qf = np.tile(self.q_full, (len(q), 1))
        qf[:, self.iq] = q
        nv = self.model.nv
        for k in range(len(q)):
            vf, af = np.zeros(nv), np.zeros(nv)
            vf[self.iv], af[self.iv] = v[k], a[k]
            Y = pin.computeJointTorqueRegressor(self.model, self.data, qf[k], vf, af)
            rows.append(self.params.columns(Y, vf, af)[self.iv])
        return np.vstack(rows) * self.scale

    def _structural_rank(self) -> int:
        rng = np.random.default_rng(1)
        n = len(self.joints)
        q = self.limits.q_min + rng.random((4 * self.params.n // max(n, 1) + 20, n)) * (
            self.limits.q_max - self.limits.q_min)
        W = self._stack(q, rng.standard_normal(q.shape), rng.standard_normal(q.shape))
        s = np.linalg.svd(W, compute_uv=False)
        return max(1, int(np.sum(s > RANK_RTOL * s[0])))

    def evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """(log cond, constraint values >= 0 when feasible).

        Cached by x: SLSQP's finite differences ask for the objective and the constraints at the
        same points in two passes.
        """
        key = x.tobytes()
        if key in self._cache:
            return self._cache[key]
        traj = self.trajectory(x)
        q, v, a = traj.sample(self.t)
        W = self._stack(q, v, a)
        s = np.linalg.svd(W, compute_uv=False)
        cond = float(s[0] / max(s[self.rank - 1], 1e-300))
        lim = self.limits
        tau = self._torques(q, v, a)
        span = lim.q_max - lim.q_min
        g = np.concatenate([(lim.q_max - q.max(0)) / span, (q.min(0) - lim.q_min) / span,
                            1.0 - np.abs(v).max(0) / lim.v_max, 1.0 - np.abs(tau).max(0) / lim.tau_max,
                            (self.clearance(q) - SELF_CLEARANCE_M) / CLEARANCE_SCALE_M])
        if len(self._cache) > 4 * x.size + 16:
            self._cache.clear()
        self._cache[key] = (float(np.log(cond)), g)
        return self._cache[key]

    def _torques(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        out = np.empty_like(q)
        nv = self.model.nv
        qf = self.q_full.copy()
        for k in range(len(q)):
            vf, af = np.zeros(nv), np.zeros(nv)
            qf[self.iq], vf[self.iv], af[self.iv] = q[k], v[k], a[k]
            out[k] = pin.rnea(self.model, self.data, qf, vf, af)[self.iv]
        return out

    def within_limits(self, x: np.ndarray, oversample: int = 8) -> bool:
        """Every limit holds on a grid ``oversample`` times finer than the design's."""
        t = np.linspace(0.0, self.period_s, oversample * len(self.t), endpoint=False)
        q, v, a = self.trajectory(x).sample(t)
        lim = self.limits
        return bool(np.all(q <= lim.q_max) and np.all(q >= lim.q_min) and np.all(np.abs(v) <= lim.v_max)
                    and np.all(np.abs(self._torques(q, v, a)) <= lim.tau_max)
                    and np.all(self.clearance(q) >= SELF_CLEARANCE_M))

    def limit_use(self, x: np.ndarray) -> np.ndarray:
        _, g = self.evaluate(x)
        n = len(self.joints)
        q_use = 1.0 - np.minimum(g[:n], g[n:2 * n]).min()
        return np.array([q_use, 1.0 - g[2 * n:3 * n].min(), 1.0 - g[3 * n:4 * n].min()])


def design_excitation(robot: Robot, joints: Sequence[str], q_start: npt.ArrayLike, *,
                      limits: ExcitationLimits | None = None, period_s: float = 10.0, harmonics: int = 5,
                      n_samples: int = 80, bodies: Sequence[str] | None = None, seed: int = 0,
                      max_iterations: int = 100, self_clearance: bool = True) -> ExcitationDesign:
    """Optimise a Fourier excitation of ``joints`` from ``q_start`` (see the module docstring).

    Args:
        robot: The nominal robot (a fixed base; weld a floating one first).
        joints: Joints to move (1-dof, actuated); the others hold ``q_start``.
        q_start: Start configuration (nq,), Pinocchio convention.
        limits: Bounds (default :meth:`ExcitationLimits.from_robot`).
        period_s: Period of the fundamental [s].
        harmonics: Harmonics per joint, 1 to :data:`MAX_HARMONICS`.
        n_samples: Samples per period in the design, at least :data:`SAMPLES_PER_HARMONIC` per
            harmonic.
        bodies: Bodies whose parameters the regressor covers (default: every body with mass).
        seed: Seed of the random start.
        max_iterations: SLSQP iterations at most.
        self_clearance: Keep the robot's own geom pairs :data:`SELF_CLEARANCE_M` apart (a constraint
            per pair and sample); False when the caller checks the clearance of a motion this
            design is only part of (e.g. the G1's waist and two arms, designed apart).

    Raises:
        InvalidPlanningInput: Bad joints, period, harmonics or samples.
    """
    joints = tuple(joints)
    if not joints:
        raise InvalidPlanningInput("joints must name at least one joint to excite")
    for j in joints:
        if robot.joint(j).nv != 1:
            raise InvalidPlanningInput(f"joint {j!r} is not a 1-dof joint; excite hinges and slides only")
    if not 1 <= harmonics <= MAX_HARMONICS:
        raise InvalidPlanningInput(f"harmonics must be 1 to {MAX_HARMONICS} (more only slow the design; see "
                                   f"MAX_HARMONICS); got {harmonics}")
    if n_samples < SAMPLES_PER_HARMONIC * harmonics:
        raise InvalidPlanningInput(f"n_samples must be >= {SAMPLES_PER_HARMONIC} per harmonic "
                                   f"({SAMPLES_PER_HARMONIC * harmonics} for {harmonics}); got {n_samples}")
    if not (np.isfinite(period_s) and period_s > 0):
        raise InvalidPlanningInput(f"period_s must be a positive number of seconds; got {period_s}")
    q_full = robot.converter.check_q(q_start, "q_start")
    with single_threaded_blas():
        return _design(robot, joints, q_full, limits, period_s, harmonics, n_samples, bodies, seed,
                       max_iterations, self_clearance)


def _design(robot: Robot, joints: tuple[str, ...], q_full: np.ndarray, limits: ExcitationLimits | None,
            period_s: float, harmonics: int, n_samples: int, bodies: Sequence[str] | None, seed: int,
            max_iterations: int, self_clearance: bool = True) -> ExcitationDesign:
    from scipy.optimize import minimize

    limits = limits or ExcitationLimits.from_robot(robot, joints, q_full)
    params = ParameterSet(robot, bodies)
    ev = _Evaluator(robot, joints, q_full, params, limits, period_s, harmonics, n_samples, self_clearance)
    x0 = _feasible_start(ev, np.random.default_rng(seed))
    cond0 = float(np.exp(ev.evaluate(x0)[0]))
    result = minimize(lambda x: ev.evaluate(x)[0], x0, method="SLSQP",
                      constraints=[{"type": "ineq", "fun": lambda x: ev.evaluate(x)[1]}],
                      options={"maxiter": max_iterations, "ftol": 1e-4})
    x = result.x
    for _ in range(100):  # SLSQP may end a hair outside a limit, or between samples: shrink inside
        if ev.within_limits(x):
            break
        x = 0.98 * x
    if not ev.within_limits(x) or ev.evaluate(x)[0] > ev.evaluate(x0)[0]:
        x = x0
    clearance = None
    if len(ev.pairs):  # on the fine grid, as the limits were checked
        t = np.linspace(0.0, ev.period_s, 8 * len(ev.t), endpoint=False)
        clearance = float(ev.clearance(ev.trajectory(x).sample(t)[0]).min())
    return ExcitationDesign(ev.trajectory(x), float(np.exp(ev.evaluate(x)[0])), cond0, ev.rank,
                            int(result.nit), ev.limit_use(x), limits, ev.pairs.labels, clearance)


def _self_pairs(robot: Robot, q_full: np.ndarray, joints: Sequence[str]) -> GeomPairs:
    """The robot's own geom pairs that can touch (``robot:robot``) and that ``joints`` move.

    Less those within :data:`SELF_CLEARANCE_M` at the start (neighbours the model keeps that close),
    and those whose relative pose no excited joint changes (both geoms below the same excited
    joints, e.g. the legs while the G1's upper body is excited: 1 of 3 G1 pairs are such).
    """
    try:
        pairs = resolve_pairs(robot, [CollisionPair(("robot",), ("robot",))])
    except CollisionPairError:  # no two of its geoms can touch
        return GeomPairs(np.zeros((0, 2), dtype=int), ())
    m = robot.mj_model
    moved = _moved_by(m, {int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)])
                          for j in joints})
    body = m.geom_bodyid[pairs.ids]
    relative = np.array([bool(moved[a] ^ moved[b]) for a, b in body], dtype=bool)
    d = PlantKinematics(robot=robot).at(q_full)
    keep = relative & (pair_distances(m, d, pairs.ids, CLEARANCE_SCALE_M) > SELF_CLEARANCE_M)
    return GeomPairs(pairs.ids[keep], tuple(label for label, k in zip(pairs.labels, keep, strict=True) if k))


def _moved_by(m: mujoco.MjModel, joint_bodies: set[int]) -> list[frozenset[int]]:
    """For each body, the bodies among ``joint_bodies`` on its path to the world (its moving joints)."""
    out: list[frozenset[int]] = [frozenset()] * m.nbody
    for b in range(1, m.nbody):  # parents come before their children in MuJoCo's body order
        parent = out[int(m.body_parentid[b])]
        out[b] = parent | {b} if b in joint_bodies else parent
    return out


def _feasible_start(ev: _Evaluator, rng: np.random.Generator) -> np.ndarray:
    """Random coefficients (amplitude ~ 1/l) shrunk until every limit holds."""
    n, L = len(ev.joints), ev.L
    span = ev.limits.q_max - ev.limits.q_min
    # harmonic l moves the joint by about a / (l w): position amplitudes fall as 1/l
    amp = 0.25 * span * 2 * np.pi / ev.period_s
    x = (rng.standard_normal((2, n, L)) * amp[None, :, None]).ravel()
    for _ in range(60):
        if ev.within_limits(x):
            return x
        x = 0.8 * x
    _, g = ev.evaluate(np.zeros_like(x))  # standing still at the start
    kinds = ("upper position", "lower position", "speed", "torque")
    worst = int(np.argmin(g))
    if worst >= 4 * n:  # a self pair (not possible at the start: those are left out)
        raise InvalidPlanningInput(f"no feasible excitation, even at small amplitude: the robot's geoms "
                                   f"{ev.pairs.labels[worst - 4 * n]} come within {SELF_CLEARANCE_M} m")
    joint = ev.joints[worst % n]
    raise InvalidPlanningInput(
        f"no feasible excitation, even at small amplitude: at rest at the start, joint {joint!r} is "
        f"already at its {kinds[worst // n]} limit ({1.0 - g[worst]:.2f} of it); move q_start or widen "
        "that limit")
