"""From a recorded log to identification samples: checks, noise, filtering, accelerations, exclusions.

A :class:`RecordedLog` is what a robot records (Pinocchio's convention): time, q, v, the joint
torques the actuators applied, and for a robot on its feet which contact bodies touched the
ground (and, when a force sensor or the plant measured them, their wrenches), and how many
contacts touched the robot elsewhere. :func:`prepare_samples` turns it into :class:`Samples`:

1. Zero-phase low-pass (Butterworth, ``scipy.signal.sosfiltfilt``) of q, v and the torques with
   the same filter, so the linear relation between them is kept; quaternions renormalised.
2. Accelerations by forward differences of the (filtered) v: the torque held from one sample to
   the next is what changed v over that period (a semi-implicit Euler plant step, exactly; a
   central difference would be half a sample late).
3. Decimation to ``rate_hz`` (the samples of a smooth excitation are strongly correlated).
4. Exclusion of samples the model cannot explain: filter transients at both ends, within
   ``margin_s`` of a contact change (impacts), while anything but the contact bodies touches the
   robot (self-collision, a wall), and near a joint limit (its constraint force is unmodelled).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from mbctl.robots.identification.exceptions import BadLogError
from mbctl.robots.model_pair import Robot

#: Fewest samples, and shortest duration [s], a log must have after exclusions.
MIN_SAMPLES = 50
MIN_DURATION_S = 1.0
#: Distance [rad or m] to a joint limit under which a sample is excluded.
LIMIT_MARGIN = 0.01


@dataclass(frozen=True)
class RecordedLog:
    """A robot's log, Pinocchio's convention.

    Attributes:
        t_s: Times (N,) [s], increasing, uniformly spaced.
        q: Configurations (N, nq).
        v: Velocities (N, nv).
        tau: Joint torques the actuators applied (N, k) [N m] (or [N] on slides).
        joints: The 1-dof joints of ``tau``'s columns (k,).
        contact_bodies: Bodies that may touch the ground (feet), or ().
        contacts: Whether each contact body touched (N, c) bool, or None.
        wrenches: Measured contact wrenches (N, c, 6), force then moment about the body origin
            [N, N m], world axes; or None.
        other_contacts: Contacts on the robot other than the contact bodies (N,) int, or None.
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    joints: tuple[str, ...]
    contact_bodies: tuple[str, ...] = ()
    contacts: np.ndarray | None = None
    wrenches: np.ndarray | None = None
    other_contacts: np.ndarray | None = None

    @property
    def dt_s(self) -> float:
        """Sample period [s]."""
        return float(np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else 0.0

    @property
    def duration_s(self) -> float:
        """Time covered [s]."""
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) else 0.0


@dataclass(frozen=True)
class Samples:
    """Identification samples (M of them), Pinocchio's convention.

    Attributes:
        t_s: Times (M,) [s].
        q: Configurations (M, nq).
        v: Velocities (M, nv).
        a: Accelerations (M, nv).
        tau: Generalized actuation (M, nv): the joint torques at their joints' v index, 0 elsewhere.
        contacts: Contact flags (M, c) bool (c = 0 for a fixed base).
        contact_bodies: Names of the contact bodies (c,).
        wrenches: Measured contact wrenches (M, c, 6) or None.
        excluded: Samples dropped, by reason (before decimation).
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    contacts: np.ndarray
    contact_bodies: tuple[str, ...]
    wrenches: np.ndarray | None = None
    excluded: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t_s)

    def take(self, index: np.ndarray | slice) -> Samples:
        """The samples at ``index``."""
        return replace(self, t_s=self.t_s[index], q=self.q[index], v=self.v[index], a=self.a[index],
                       tau=self.tau[index], contacts=self.contacts[index],
                       wrenches=None if self.wrenches is None else self.wrenches[index])


def check_log(robot: Robot, log: RecordedLog) -> None:
    """Shapes, names, finite values and length of ``log`` against ``robot``.

    Raises:
        BadLogError: Another robot's joints, wrong shapes, NaN/inf (names the column and row),
            non-increasing time, or too short.
    """
    n = len(log.t_s)
    unknown = [j for j in log.joints if j not in robot.joints]
    if unknown:
        raise BadLogError(f"the log's torques are for joints {unknown[:5]} that {robot.name!r} does not "
                          f"have: another robot's log? ({robot.name!r} has {list(robot.joints)[:5]} ...)")
    shapes = {"q": (log.q.shape, (n, robot.nq)), "v": (log.v.shape, (n, robot.nv)),
              "tau": (log.tau.shape, (n, len(log.joints)))}
    for name, (got, want) in shapes.items():
        if got != want:
            raise BadLogError(f"log {name} has shape {got}; {robot.name!r} needs {want}: another "
                              "robot's log?")
    for name, arr in (("time_s", log.t_s[:, None]), ("q", log.q), ("v", log.v), ("tau", log.tau)):
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            row, col = (int(x) for x in bad[0])
            raise BadLogError(f"the log has {len(bad)} non-finite values in {name}, the first at data row "
                              f"{row}, {name} column {col}; clean or cut the log")
    if n < MIN_SAMPLES or log.duration_s < MIN_DURATION_S:
        raise BadLogError(f"the log is too short: {n} rows over {log.duration_s:.3g} s; identification "
                          f"needs at least {MIN_SAMPLES} rows and {MIN_DURATION_S:g} s (record a longer "
                          "excitation)")
    if np.any(np.diff(log.t_s) <= 0):
        raise BadLogError("the log's time_s is not increasing")
    if log.contacts is not None and log.contacts.shape != (n, len(log.contact_bodies)):
        raise BadLogError(f"contact flags have shape {log.contacts.shape}; expected "
                          f"{(n, len(log.contact_bodies))}")


def add_noise(robot: Robot, log: RecordedLog, torque_pct: float = 0.0, encoder_rad: float = 0.0,
              seed: int = 0) -> RecordedLog:
    """The log as noisy sensors would have recorded it (a study of sensor quality).

    Torques get white noise of ``torque_pct`` % of each joint's RMS torque over the log. The
    joint encoders (the 1-dof joints' q; a floating base's pose is left exact) get white noise of
    ``encoder_rad``, and v the difference of that noise over one sample (a velocity from encoder
    differences).
    """
    rng = np.random.default_rng(seed)
    tau, q, v = log.tau.copy(), log.q.copy(), log.v.copy()
    if torque_pct:
        rms = np.sqrt(np.mean(tau**2, axis=0))
        tau += rng.standard_normal(tau.shape) * rms * torque_pct / 100.0
    if encoder_rad:
        iq = [j.idx_q for j in robot.joints.values() if j.nq == 1]
        iv = [j.idx_v for j in robot.joints.values() if j.nq == 1]
        noise = rng.standard_normal((len(q), len(iq))) * encoder_rad
        q[:, iq] += noise
        v[:, iv] += np.vstack([np.zeros((1, len(iv))), np.diff(noise, axis=0)]) / log.dt_s
    return replace(log, q=q, v=v, tau=tau)


def _lowpass(x: np.ndarray, cutoff_hz: float, rate_hz: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, cutoff_hz, fs=rate_hz, output="sos")
    return sosfiltfilt(sos, x, axis=0)


def _window(flags: np.ndarray, half: int) -> np.ndarray:
    """``flags`` (N,) bool widened by ``half`` samples on each side."""
    if half <= 0 or not flags.any():
        return flags
    kernel = np.ones(2 * half + 1)
    return np.convolve(flags.astype(float), kernel, mode="same") > 0


def prepare_samples(robot: Robot, log: RecordedLog, cutoff_hz: float | None = 10.0,
                    rate_hz: float | None = 100.0, margin_s: float = 0.1) -> Samples:
    """Filtered, differentiated, decimated samples with the unexplainable ones excluded.

    Args:
        robot: The nominal model pair (joint limits, the free-flyer's quaternion).
        log: The recorded log (checked with :func:`check_log` first).
        cutoff_hz: Low-pass cutoff [Hz], or None for no filter (forward differences).
        rate_hz: Decimate to about this rate [Hz] (None: keep every sample).
        margin_s: Half-width [s] of the exclusion windows around contact changes and other contacts.

    Raises:
        BadLogError: Too few samples left after the exclusions.
    """
    check_log(robot, log)
    dt = log.dt_s
    fs = 1.0 / dt
    q, v, tau = log.q.astype(float), log.v.astype(float), log.tau.astype(float)
    n = len(q)
    filtered = cutoff_hz is not None and cutoff_hz > 0
    if filtered:
        if cutoff_hz >= 0.5 * fs:  # type: ignore[operator]
            raise BadLogError(f"cutoff {cutoff_hz} Hz is at or above the log's Nyquist frequency "
                              f"{0.5 * fs:g} Hz; choose a lower --cutoff-hz")
        q, v, tau = (_lowpass(x, cutoff_hz, fs) for x in (q, v, tau))  # type: ignore[arg-type]
    # forward differences: the torque held over [t_k, t_k+1) is what changed v_k into v_k+1
    a = np.vstack([np.diff(v, axis=0) / dt, np.zeros((1, v.shape[1]))])
    if robot.has_floating_base:  # the filtered quaternion back on the unit sphere
        base = next(iter(robot.joints.values()))
        quat = slice(base.idx_q + 3, base.idx_q + 7)
        q[:, quat] /= np.linalg.norm(q[:, quat], axis=1, keepdims=True)
    tau_gen = np.zeros_like(v)
    for k, j in enumerate(log.joints):
        tau_gen[:, robot.joint(j).idx_v] += tau[:, k]
    excluded: dict[str, int] = {}
    drop = np.zeros(n, dtype=bool)
    edge = int(np.ceil((3.0 / cutoff_hz if filtered else 0.0) / dt)) + 1  # type: ignore[operator]
    ends = np.zeros(n, dtype=bool)
    ends[:edge] = ends[-edge:] = True  # the last sample has no forward difference
    half = int(round(margin_s / dt))
    contacts = log.contacts if log.contacts is not None else np.zeros((n, 0), dtype=bool)
    change = np.zeros(n, dtype=bool)
    if contacts.shape[1]:
        change[1:] = np.any(contacts[1:] != contacts[:-1], axis=1)
    others = (log.other_contacts > 0) if log.other_contacts is not None else np.zeros(n, dtype=bool)
    model = robot.pin_model
    lo, hi = np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
    limited = (lo > -1e6) & (hi < 1e6)  # hinges and slides with limits (not free-flyer bounds)
    if robot.has_floating_base:
        limited[:7] = False
    near = np.any((log.q[:, limited] < lo[limited] + LIMIT_MARGIN)
                  | (log.q[:, limited] > hi[limited] - LIMIT_MARGIN), axis=1)
    for reason, flags in (("filter transients at the ends", ends),
                          ("contact changes (impacts)", _window(change, half)),
                          ("other contacts on the robot", _window(others, half)),
                          ("near a joint limit", _window(near, half))):
        new = flags & ~drop
        if new.any():
            excluded[reason] = int(new.sum())
        drop |= flags
    step = max(1, int(round(fs / rate_hz))) if rate_hz else 1
    keep = np.flatnonzero(~drop)
    keep = keep[(keep % step) == 0]
    if len(keep) < MIN_SAMPLES:
        raise BadLogError(f"only {len(keep)} samples are left after the exclusions {excluded} (need "
                          f"{MIN_SAMPLES}); record a longer log with fewer contacts or limit hits")
    wrenches = log.wrenches[keep] if log.wrenches is not None else None
    return Samples(log.t_s[keep], q[keep], v[keep], a[keep], tau_gen[keep], contacts[keep].astype(bool),
                   log.contact_bodies, wrenches, excluded)


def split(samples: Samples, validation_fraction: float) -> tuple[Samples, Samples]:
    """(training, validation): the validation part is the last ``validation_fraction`` of the time.

    Raises:
        BadLogError: A fraction outside (0, 0.9] or too few samples on either side.
    """
    if not 0.0 < validation_fraction <= 0.9:
        raise BadLogError(f"validation fraction must be in (0, 0.9]; got {validation_fraction}")
    t_split = samples.t_s[0] + (1.0 - validation_fraction) * (samples.t_s[-1] - samples.t_s[0])
    train = samples.t_s < t_split
    if train.sum() < MIN_SAMPLES // 2 or (~train).sum() < 2:
        raise BadLogError(f"{int(train.sum())} training and {int((~train).sum())} validation samples: "
                          "too few; record a longer log")
    return samples.take(np.flatnonzero(train)), samples.take(np.flatnonzero(~train))
