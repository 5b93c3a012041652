"""Both engines over the cross-check's states: per state the engine calls, per chunk the rest.

Per state only what an engine must do for that state runs: Pinocchio's ``computeAllTerms`` (its
joint placements ``oMi`` and joint Jacobians ``J`` read), kinetic energy, ABA and RNEA; MuJoCo's
``mj_forward``, one ``mj_jacBody`` / ``mj_jacSite`` per compared frame, ``mj_fullM``, the subtree
quantities, ``mj_inverse`` and ``mj_rne`` at zero velocity. Their outputs are copied into buffers
of ``chunk`` states through views made once (``_make_slots``; all joint placements in one copy
through a view of ``data.oMi``, ``frames.joint_placements_view``). Everything else is done once
per chunk with batched numpy: the MuJoCo inputs in MuJoCo's convention, the outputs back into
Pinocchio's (``StateConverter.velocity_maps``: ``T(q)`` block by block), and the error reduction,
in place in preallocated buffers (a fresh temporary per operation costs more than the operation).

Pinocchio's frame placements are formed per chunk the way ``updateFramePlacements`` forms them,
``X_WF = X_WJ X_JF`` from the joint placements (the product only for frames away from their
joint), and its frame Jacobians from the joint Jacobians (``frames.frame_jacobians``); the test
suite checks both against Pinocchio's functions. MuJoCo's frame Jacobians stay its own calls, so
the comparison still checks one engine's Jacobian routine against the other's. Only the Jacobian
entries in the union of both engines' supports are compared, packed (``frames.jacobian_packing``;
MuJoCo's per state, right after its calls).

The compared frames and the Jacobian supports are in ``frames``; ``match_frames`` and
``frame_jacobians`` are re-exported here.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from itertools import starmap

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.conventions import VelocityMaps
from mbctl.robots.crosscheck.frames import (
    Frames,
    frame_jacobians,
    jacobian_packing,
    joint_placements_view,
    match_frames,
    mj_support_mask,
    support_mask,
)
from mbctl.robots.crosscheck.plant import static_bodies, top_moving_bodies
from mbctl.robots.crosscheck.sampling import States
from mbctl.robots.crosscheck.tolerances import TOLERANCES
from mbctl.robots.model_pair import Robot

__all__ = ["CHUNK_SIZE", "GROUPS", "SINGLES", "Evaluator", "Frames", "frame_jacobians", "match_frames",
           "mj_support_mask", "support_mask"]

_HOMOGENEOUS = pin.SE3.homogeneous.fget


def _pin_outputs(pd: pin.Data) -> tuple[np.ndarray, ...]:
    """``computeAllTerms``'s outputs the cross-check copies: J, M, nle, g, com, Jcom, hg."""
    return pd.J, pd.M, pd.nle, pd.g, pd.com[0], pd.Jcom, pd.hg.vector


#: States evaluated between two batched conversions and error reductions: long enough to spread
#: the cost of the numpy calls per chunk, short enough that the chunk's buffers stay in cache
#: (measured on the G1, same process, interleaved: 64 takes 0.97-0.975x the time of 32, 48 0.97-0.99x,
#: 128 no better; the 2-link arm 0.88x).
CHUNK_SIZE = 64

#: Quantities kept side by side in one buffer, so that each group costs one set of numpy calls:
#: generalized forces and accelerations (c, 4, nv), energies (c, 2) and 3-vectors (c, 3, 3).
GROUPS = {
    "vectors": ("bias", "gravity", "forward_dynamics", "inverse_dynamics"),
    "energies": ("kinetic_energy", "potential_energy"),
    "points": ("com", "momentum_linear", "momentum_angular"),
}
#: The other quantities, each in a buffer of its own.
SINGLES = ("mass_matrix", "com_jacobian")


class Evaluator:
    """Buffers and engine data, allocated once and reused for every chunk of states."""

    def __init__(self, robot: Robot, m: mujoco.MjModel, frames: Frames, chunk: int):
        """Prepare both engines for ``robot``: ``m`` is MuJoCo's comparison model (a copy)."""
        self.robot, self.m, self.frames, self.chunk = robot, m, frames, chunk
        self.pm = robot.pin_model
        self.pd = self.pm.createData()
        self.d = mujoco.MjData(m)
        nv, nvp, nf = robot.nv, m.nv, len(frames.pin_ids)
        # Kinetic energy like with like: MuJoCo's 1/2 v^T M v has the armature in M, while
        # Pinocchio 4.1's computeKineticEnergy leaves out the armature of revolute joints with an
        # unaligned axis. So Pinocchio's energy of the rigid bodies alone (the same model without
        # armature, on the same data) plus 1/2 v^T diag(armature) v.
        self._pm_rigid = self.pm.copy()
        self._pm_rigid.armature = np.zeros(nv)
        self._half_armature = 0.5 * np.asarray(self.pm.armature, dtype=float)
        # The robot's coordinates in the plant; the scene's (a free box) stay at qpos0, at rest.
        self.qi, self.vi = robot.qpos_index, robot.qvel_index
        self.vv = np.ix_(self.vi, self.vi) if isinstance(self.vi, np.ndarray) else (self.vi, self.vi)
        in_robot = set(robot.robot_body_ids)
        self.tops = np.array([b for b in top_moving_bodies(m) if b in in_robot], dtype=int)
        self.top_mass = np.array(m.body_subtreemass[self.tops])
        # Bodies that do not move in the comparison: welded to the world, or scene.
        self.static = np.array(sorted(set(static_bodies(m).tolist()) | set(robot.scene_body_ids)), dtype=int)
        self._pe_static = 0.0
        self._pe_static_known = False
        # Frame placements as updateFramePlacements forms them, X_WF = X_WJ X_JF, batched per
        # chunk: one placement per joint (31 on the G1) is fetched per state, not one per frame (50).
        self._frame_joint = np.array([self.pm.frames[f].parentJoint for f in frames.pin_ids], dtype=int)
        X_JF = [self.pm.frames[f].placement.homogeneous for f in frames.pin_ids]
        self._X_JF = np.array(X_JF).reshape(nf, 4, 4)
        # Most frames sit at their joint (44 of 50 on the G1): X_WF = X_WJ, no product needed.
        self._moved = np.flatnonzero(np.any(self._X_JF != np.eye(4), axis=(1, 2)))
        # Placements are kept transposed, (c, 4, 3, nf) for [R_WF | p_WF] (c, nf, 3, 4): positions and
        # rotations are then contiguous blocks (reductions over them, p_WF for the Jacobians).
        self._X_pin = np.zeros((chunk, 4, 3, nf))
        self._mask = support_mask(self.pm, frames.pin_ids)
        # The (frame, column) entries the Jacobians are compared on: the union of both supports.
        union = (self._mask + mj_support_mask(robot, m, frames)) > 0
        self._pk_frame, self._pk_col, self._pk_free = jacobian_packing(union, robot.converter.free_v)
        self._pk_in_pin = self._mask[self._pk_frame, self._pk_col]  # 0 where only MuJoCo's chain has it
        self._pk_pin_all = bool(np.all(self._pk_in_pin))
        # Flat indices of the compared entries in MuJoCo's (nf, 6, nvp) Jacobians (plant columns).
        plant_col = np.arange(nvp)[self.vi][self._pk_col]
        self._pk_mj = self._pk_frame * 6 * nvp + np.arange(6)[:, None] * nvp + plant_col  # (6, L)
        # Pinocchio's crba fills the upper triangle: the lower one is copied from it per chunk,
        # as one gather and one scatter on the flat matrices (2-d fancy indexing costs more).
        lo, up = np.tril_indices(nv, -1)
        self._tril_lo, self._tril_up = lo * nv + up, up * nv + lo
        self._M_upper = np.zeros((chunk, lo.size))
        # Pinocchio's outputs per state, in its convention.
        self._p_vectors = np.zeros((chunk, 4, nv))  # nle, g, aba, rnea (GROUPS["vectors"] order)
        self._p_energies = np.zeros((chunk, 2))
        self._p_points = np.zeros((chunk, 3, 3))  # com, then hg (linear, angular)
        self._p_M = np.zeros((chunk, nv, nv))
        self._p_Jcom = np.zeros((chunk, 3, nv))
        # per state the columns of [R_WJ | p_WJ] of every joint, read through one view of pd.oMi
        self._X_WJ = np.zeros((chunk, self.pm.njoints, 4, 3))
        self._oMi = joint_placements_view(self.pd)
        self._J_world = np.zeros((chunk, 6, nv))
        # Pinocchio returns (6, nv) and (3, nv) matrices as vectors when nv = 1: write through views.
        self._J_world_out = self._J_world[..., 0] if nv == 1 else self._J_world
        self._Jcom_out = self._p_Jcom[..., 0] if nv == 1 else self._p_Jcom
        self._hg_out = self._p_points[:, 1:].reshape(chunk, 6)
        # MuJoCo's raw outputs per state, in its convention and the plant's size.
        # placements of all bodies, then all sites, transposed as _X_pin: the compared ones are one
        # gather per chunk
        self._X_all = np.zeros((chunk, 4, 3, m.nbody + m.nsite))
        self._frame_rows = np.concatenate([frames.mj_body_ids, m.nbody + frames.mj_site_ids]).astype(int)
        self._J_mj = np.zeros((nf, 6, nvp))  # one state's, packed into _J_mj_packed right away
        self._J_mj_packed = np.zeros((chunk, 6, self._pk_col.size))
        self._M_mj = np.zeros((chunk, nvp, nvp))
        self._m_vectors = np.zeros((chunk, 4, nvp))  # qfrc_bias, rne at v = 0, qacc, qfrc_inverse
        self._energy = np.zeros((chunk, 2))
        self._X_mj = np.zeros((chunk, 4, 3, nf))
        self._m_points = np.zeros((chunk, 3, 3))  # p_WC, momentum: linear, angular about C
        nt = self.tops.size
        self._Jsub = np.zeros((chunk, nt, 3, nvp))
        self._sub = np.zeros((chunk, 3, m.nbody, 3))  # subtree com, linear velocity, angular momentum
        # The arguments of every Jacobian call, with output views, made once per slot:
        # (m, d, jacp (3, nvp), jacr (3, nvp), body or site id), bodies then sites.
        nb = frames.mj_body_ids.size
        J = self._J_mj
        self._jac_body_args = [(m, self.d, J[k, :3], J[k, 3:], int(b))
                               for k, b in enumerate(frames.mj_body_ids)]
        self._jac_site_args = [(m, self.d, J[k, :3], J[k, 3:], int(s))
                               for k, s in enumerate(frames.mj_site_ids, start=nb)]
        self._J_diff = np.zeros((chunk, 6, self._pk_col.size))
        L = self._pk_col.size
        # The free joints' linear columns come first in the packing; their angular rows are exact
        # zeros (a translation turns no frame), so the shift to the frame's origin starts after them.
        self._pk_turn = 3 * sum(F for _, F in self._pk_free)
        self._pk_J = np.zeros((chunk, 6, L))
        turned = L - self._pk_turn
        self._pk_tmp, self._pk_p = np.zeros((chunk, turned)), np.zeros((chunk, 3, turned))
        self._make_slots()

    def _make_slots(self) -> None:
        """Views made once: MjData's arrays, and per buffer slot the rows each state writes.

        Every attribute access of MjData and every indexing of a buffer builds a new array (0.1-0.3
        us); a state writes about 30 of them, so they are built here, not per state.
        """
        m, d, chunk = self.m, self.d, self.chunk
        # MuJoCo's inputs in the plant's size, filled per chunk: the scene's coordinates stay at
        # qpos0 and at rest (zero qvel, qfrc_applied and qacc), so a state is whole-array copies.
        self._in_qpos = np.tile(m.qpos0, (chunk, 1))
        self._in_v = np.zeros((3, chunk, m.nv))  # qvel, qfrc_applied, qacc
        self._d_in = (d.qpos, d.qvel, d.qfrc_applied, d.qacc)
        # MuJoCo's outputs, and per slot (_mj_slots) where each goes, in the same order
        self._d_out = (d.xpos, d.xmat.reshape(-1, 3, 3), d.site_xpos, d.site_xmat.reshape(-1, 3, 3),
                       d.qfrc_bias, d.qacc, d.energy, d.subtree_com, d.subtree_linvel, d.subtree_angmom,
                       d.qfrc_inverse)
        self._J_mj_flat = self._J_mj.reshape(-1)
        # Pinocchio's outputs as views into pd, read once; None when a read returns a copy
        views = _pin_outputs(self.pd)
        same = all(a.ctypes.data == b.ctypes.data for a, b in zip(views, _pin_outputs(self.pd), strict=True))
        self._pd_views = views if same else None
        self._pin_energies: list[tuple[float, float]] = []  # per state of the chunk (kinetic, potential)
        p_vec, m_vec = self._p_vectors, self._m_vectors
        X_all, nb = self._X_all, m.nbody
        self._pin_slots = [
            (self._X_WJ[i], self._J_world_out[i], self._p_M[i], p_vec[i, 0], p_vec[i, 1],
             self._p_points[i, 0], self._Jcom_out[i], self._hg_out[i], p_vec[i, 2], p_vec[i, 3])
            for i in range(chunk)
        ]
        self._mj_slots = [
            ((self._in_qpos[i], self._in_v[0, i], self._in_v[1, i], self._in_v[2, i]),
             (X_all[i, 3, :, :nb].T, X_all[i, :3, :, :nb].T, X_all[i, 3, :, nb:].T, X_all[i, :3, :, nb:].T,
              m_vec[i, 0], m_vec[i, 2], self._energy[i], self._sub[i, 0], self._sub[i, 1], self._sub[i, 2],
              m_vec[i, 3]),
             self._J_mj_packed[i], self._M_mj[i], m_vec[i, 1],
             [(m, d, self._Jsub[i, k], int(r)) for k, r in enumerate(self.tops)])
            for i in range(chunk)
        ]

    # ------------------------------------------------------------------ per state
    def _pin_state(self, i: int, q: np.ndarray, v: np.ndarray, tau: np.ndarray, a: np.ndarray) -> None:
        pm, pd = self.pm, self.pd
        X_WJ, J, M, nle, g, com, Jcom, hg, fd, id_ = self._pin_slots[i]
        pin.computeAllTerms(pm, pd, q, v)
        if self._oMi is not None:
            X_WJ[...] = self._oMi
        else:  # Pinocchio's memory layout is not the one joint_placements_view reads: one by one
            X_WJ[...] = np.array(list(map(_HOMOGENEOUS, pd.oMi.tolist())))[:, :3].transpose(0, 2, 1)
        J_, M_, nle_, g_, com_, Jcom_, hg_ = self._pd_views or _pin_outputs(pd)
        J[...] = J_
        M[...] = M_  # upper triangle; symmetrized per chunk
        nle[...] = nle_
        g[...] = g_
        com[...] = com_
        Jcom[...] = Jcom_
        hg[...] = hg_
        # the rigid bodies' energy from pd.v (the armature's is added per chunk); plain floats,
        # converted once per chunk
        self._pin_energies[i] = (pin.computeKineticEnergy(self._pm_rigid, pd), pd.potential_energy)
        fd[...] = pin.aba(pm, pd, q, v, tau)
        id_[...] = pin.rnea(pm, pd, q, v, a)

    def _mj_state(self, i: int) -> None:
        m, d = self.m, self.d
        inputs, outputs, J_packed, M, gravity, jac_subtree_args = self._mj_slots[i]
        d_qpos, d_qvel, d_qfrc, d_qacc = self._d_in
        qpos, qvel, qfrc, qacc = inputs
        d_qpos[...] = qpos
        d_qvel[...] = qvel
        d_qfrc[...] = qfrc
        mujoco.mj_forward(m, d)
        deque(starmap(mujoco.mj_jacBody, self._jac_body_args), maxlen=0)  # the loops in C
        deque(starmap(mujoco.mj_jacSite, self._jac_site_args), maxlen=0)
        # only the compared entries are kept (the rest are zeros in both engines): small buffers.
        # mode="clip": with "raise" numpy checks every index and writes through a temporary.
        self._J_mj_flat.take(self._pk_mj, out=J_packed, mode="clip")
        mujoco.mj_fullM(m, d, M)
        deque(starmap(mujoco.mj_jacSubtreeCom, jac_subtree_args), maxlen=0)
        mujoco.mj_subtreeVel(m, d)
        if not self._pe_static_known:  # bodies welded to the world and the scene do not move
            s = self.static
            self._pe_static = float(-np.sum(m.body_mass[s] * (d.xipos[s] @ m.opt.gravity)))
            self._pe_static_known = True
        out, src = outputs, self._d_out  # see _make_slots for the order
        # whole arrays: a plain copy costs less than picking the frames (all but qfrc_inverse,
        # which is written below, are final after mj_subtreeVel)
        out[0][...] = src[0]
        out[1][...] = src[1]
        out[2][...] = src[2]
        out[3][...] = src[3]
        out[4][...] = src[4]
        out[5][...] = src[5]
        out[6][...] = src[6]
        out[7][...] = src[7]
        out[8][...] = src[8]
        out[9][...] = src[9]
        # Inverse dynamics at the same (q, v): the position and velocity stages are current.
        d_qacc[...] = qacc  # the scene's dofs at rest
        mujoco.mj_inverseSkip(m, d, mujoco.mjtStage.mjSTAGE_VEL, 1)
        out[10][...] = src[10]
        # Gravity: the bias force at zero velocity (mj_rne reads cvel, so recompute it).
        d_qvel.fill(0.0)
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, 0, gravity)

    # ------------------------------------------------------------------ per chunk
    def _evaluate(self, states: States, start: int, stop: int) -> None:
        """Evaluate states ``start:stop`` (at most ``chunk``) into buffer slots 0 .. stop - start."""
        conv = self.robot.converter
        c = stop - start
        q, v, tau, a = (x[start:stop] for x in (states.q, states.v, states.tau, states.a))
        self._maps = maps = conv.velocity_maps(q)
        self._Tdot_v = maps.dot_v(v)
        # MuJoCo's inputs: qpos, qvel = T v, qfrc = T tau, qacc = T a + Tdot v (batched)
        self._in_qpos[:c, self.qi] = conv.qs_pin_to_mj(q)
        in_v = self._in_v[:, :c]
        in_v[0][:, self.vi] = maps.to_mj(v)
        in_v[1][:, self.vi] = maps.to_mj(tau)
        in_v[2][:, self.vi] = maps.to_mj(a) + self._Tdot_v
        self._pin_energies = [(0.0, 0.0)] * c
        pin_state, mj_state = self._pin_state, self._mj_state
        for i, pin_args in enumerate(zip(q, v, tau, a, strict=True)):
            pin_state(i, *pin_args)
            mj_state(i)
        self._p_energies[:c] = self._pin_energies
        self._v = v

    def aligned(self, c: int, full: bool = False) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Pinocchio's and MuJoCo's values of the first ``c`` slots, in Pinocchio's convention.

        Keys: the groups of ``GROUPS`` (quantities side by side on axis 1), the ``SINGLES``,
        "frames": the placements ``[R_WF | p_WF]`` (c, nf, 3, 4), and "jacobian", all 6 rows:
        (c, 6, L) on the compared entries, or with ``full=True`` (c, nf, 6, nv) for Pinocchio and
        (1, nf, 6, nv) for MuJoCo, whose dense Jacobians are kept for the last state only.
        MuJoCo's buffers are converted in place.
        """
        maps, vi, Tdot_v = self._maps, self.vi, self._Tdot_v
        M = self._p_M[:c]
        M_flat = M.reshape(c, -1)
        M_flat[:, self._tril_lo] = M_flat.take(self._tril_up, axis=1, out=self._M_upper[:c], mode="clip")
        energies = self._p_energies[:c].copy()
        energies[:, 0] += (self._v * self._v) @ self._half_armature
        X_WJ_t = self._X_WJ[:c].transpose(0, 2, 3, 1)  # (c, 4, 3, njoints)
        X_t = X_WJ_t.take(self._frame_joint, axis=3, out=self._X_pin[:c], mode="clip")
        X_WF = X_t.transpose(0, 3, 2, 1)  # (c, nf, 3, 4), a view
        if self._moved.size:  # the frames away from their joint: X_WJ X_JF (3 x 4)
            X_WF[:, self._moved] = np.matmul(X_WF[:, self._moved], self._X_JF[self._moved])
        P = {"vectors": self._p_vectors[:c], "energies": energies, "points": self._p_points[:c],
             "mass_matrix": M, "com_jacobian": self._p_Jcom[:c], "frames": X_WF}
        if full:
            nf = len(self.frames.pin_ids)
            P["jacobian"] = frame_jacobians(
                self._J_world[:c], X_WF[..., 3], self._mask, np.zeros((c, nf, 6, self.robot.nv))
            )
        else:
            P["jacobian"] = self._packed_pin(c, X_t[:, 3])
        M_mj = maps.congruence(self._M_mj[:c][(slice(None), *self.vv)])  # the robot's block: T^T M T
        vectors = self._m_vectors[:c][..., vi]  # bias, gravity, qacc, inverse (MuJoCo's convention)
        vectors[:, 2] -= Tdot_v  # a_pin = T^T (a_mj - Tdot v)
        maps.to_pin(vectors)
        # b_pin = T^T (b_mj + M_mj Tdot v) = T^T b_mj + M_pin T^T Tdot v
        vectors[:, 0] += np.einsum("nij,nj->ni", M_mj, maps.to_pin(Tdot_v.copy()))
        # Centre of mass and momentum of the moving bodies, from the subtrees that hold them.
        w = self.top_mass / np.sum(self.top_mass)
        com, linvel, angmom = (self._sub[:c, k][:, self.tops] for k in range(3))
        points = self._m_points[:c]
        p_WC = points[:, 0] = np.einsum("k,nkj->nj", w, com)
        lin = linvel * self.top_mass[:, None]
        points[:, 1] = lin.sum(axis=1)
        points[:, 2] = angmom.sum(axis=1)
        r = com - p_WC[:, None]  # each subtree's CoM from the robot's: h_C = sum h_k + r_k x m_k v_k
        for a, b, e in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # (np.cross costs more than the rest)
            points[:, 2, a] += (r[..., b] * lin[..., e] - r[..., e] * lin[..., b]).sum(axis=1)
        energy = self._energy[:c]  # MuJoCo's order: potential, kinetic
        Q = {"vectors": vectors, "energies": np.stack([energy[:, 1], energy[:, 0] - self._pe_static], axis=1),
             "points": points, "mass_matrix": M_mj,
             "com_jacobian": maps.right(np.einsum("k,nkij->nij", w, self._Jsub[:c][..., vi])),
             "frames": self._mj_frames(c)}
        if full:  # MuJoCo's dense Jacobians are kept for the last state only: c = 1 (worst_entry)
            last = VelocityMaps(maps.free_v, maps.R[c - 1 :])
            Q["jacobian"] = last.right(np.array(self._J_mj[None][..., vi]))
        else:
            # J_mj T: T mixes only a free joint's linear columns, whose angular rows are exact zeros in
            # both engines (a translation turns no frame), so only the linear rows are turned.
            maps.right_packed(self._J_mj_packed[:c, :3], self._pk_free)
            Q["jacobian"] = self._J_mj_packed[:c]
        return P, Q

    def _mj_frames(self, c: int) -> np.ndarray:
        """MuJoCo's placements ``[R_WF | p_WF]`` (c, nf, 3, 4) of the compared bodies and sites (a view)."""
        X_t = self._X_all[:c].take(self._frame_rows, axis=3, out=self._X_mj[:c], mode="clip")
        return X_t.transpose(0, 3, 2, 1)

    def _packed_pin(self, c: int, p_T: np.ndarray) -> np.ndarray:
        """Pinocchio's frame Jacobians (c, 6, L) on the compared entries (``frame_jacobians``).

        ``p_T``: the frames' origins ``p_WF`` transposed (c, 3, nf).
        """
        # np.take into C-ordered buffers: fancy indexing on the last axis returns strided arrays,
        # on which the arithmetic below runs several times slower.
        # mode="clip": with "raise" numpy checks every index and writes through a temporary.
        J = self._J_world[:c].take(self._pk_col, axis=2, out=self._pk_J[:c], mode="clip")  # (c, 6, L)
        t = self._pk_turn  # entries before t have w = 0: v_F = v_O
        p = p_T.take(self._pk_frame[t:], axis=2, out=self._pk_p[:c], mode="clip")  # (c, 3, L - t)
        tmp, Jt = self._pk_tmp[:c], J[..., t:]
        for a, b, e in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # v_F = v_O - p_WF x w, without temporaries
            np.multiply(p[:, b], Jt[:, 3 + e], out=tmp)
            Jt[:, a] -= tmp
            np.multiply(p[:, e], Jt[:, 3 + b], out=tmp)
            Jt[:, a] += tmp
        if not self._pk_pin_all:  # entries of MuJoCo's chain outside Pinocchio's support
            J *= self._pk_in_pin
        return J

    @staticmethod
    def quantities(P: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The values of ``aligned`` by quantity name (views into the groups)."""
        out = {k: P[k] for k in SINGLES}
        out["fk_position"], out["fk_rotation"] = P["frames"][..., 3], P["frames"][..., :3]
        for group, names in GROUPS.items():
            out.update({name: P[group][:, k] for k, name in enumerate(names)})
        return out

    def run(
        self, states: States, progress: Callable[[int, int], None] | None = None
    ) -> dict[str, tuple[np.ndarray, float]]:
        """Per quantity: (abs error per state (n,), largest MuJoCo magnitude over all states).

        ``progress(done, n)`` is called after each chunk, if given.
        """
        n = len(states.kinds)
        err = {k: np.zeros(n) for k in TOLERANCES}
        scale = dict.fromkeys(TOLERANCES, 0.0)
        for start in range(0, n, self.chunk):
            stop = min(start + self.chunk, n)
            c = stop - start
            self._evaluate(states, start, stop)
            P, Q = self.aligned(c)
            for k, (diff, mag) in self._reduced(P, Q, c).items():
                err[k][start:stop] = diff
                scale[k] = max(scale[k], mag)
            if progress is not None:
                progress(stop, n)
        for e in err.values():  # a NaN (propagated through max) is an infinite error
            e[np.isnan(e)] = np.inf
        return {k: (err[k], scale[k]) for k in TOLERANCES}

    def _reduced(
        self, P: dict[str, np.ndarray], Q: dict[str, np.ndarray], c: int
    ) -> dict[str, tuple[np.ndarray, float]]:
        """Per quantity: the largest |Pinocchio - MuJoCo| per state (c,) and the largest |MuJoCo|."""
        out: dict[str, tuple[np.ndarray, float]] = {}
        for group, names in GROUPS.items():
            diff, mag = np.abs(P[group] - Q[group]), np.abs(Q[group])
            axes = tuple(range(2, diff.ndim))
            worst = diff.max(axis=axes) if axes else diff  # (c, k)
            scale = mag.max(axis=(0, *axes))  # (k,)
            out.update({name: (worst[:, k], float(scale[k])) for k, name in enumerate(names)})
        for k in SINGLES:
            if Q[k].size == 0:  # no frames
                out[k] = (np.zeros(c), 0.0)
                continue
            diff = np.abs(P[k] - Q[k]).reshape(c, -1)  # one reduction axis: several cost far more
            out[k] = (diff.max(axis=1), float(np.abs(Q[k]).max()))
        # positions and rotations at once, transposed (c, 4, 3, nf): each a contiguous block per state
        X_q = Q["frames"].transpose(0, 3, 2, 1)
        D = np.abs(P["frames"].transpose(0, 3, 2, 1) - X_q)
        for name, cols in (("fk_position", 3), ("fk_rotation", slice(0, 3))):
            if D.size == 0:
                out[name] = (np.zeros(c), 0.0)
                continue
            dx, mag = D[:, cols], X_q[:, cols]
            out[name] = (dx.reshape(c, -1).max(axis=1), float(max(mag.max(), -mag.min())))
        # The Jacobians are the bulk of the data: in place, on the compared entries (c, 6, L).
        D = self._J_diff[:c]
        Jm = Q["jacobian"]
        np.subtract(P["jacobian"], Jm, out=D)
        np.abs(D, out=D)
        np.abs(Jm, out=Jm)
        for name, rows in (("jacobian_linear", slice(0, 3)), ("jacobian_angular", slice(3, 6))):
            if D.shape[2] == 0:
                out[name] = (np.zeros(c), 0.0)
                continue
            out[name] = (D[:, rows].max(axis=(1, 2)), float(Jm[:, rows].max()))
        return out

    def worst_entry(self, states: States, s: int, quantity: str) -> tuple[int, ...]:
        """Index of the largest error of ``quantity`` within state ``s`` (first NaN if any).

        Evaluates state ``s`` again (into slot 0), so it costs one state; called for failing
        quantities only.
        """
        self._evaluate(states, s, s + 1)
        P, Q = self.aligned(1, full=True)
        rows = {"jacobian_linear": slice(0, 3), "jacobian_angular": slice(3, 6)}
        if quantity in rows:
            diff = np.abs(P["jacobian"][0] - Q["jacobian"][0])[:, rows[quantity]]
        else:
            diff = np.abs(self.quantities(P)[quantity][0] - self.quantities(Q)[quantity][0])
        if diff.ndim == 0:
            return ()
        flat = int(np.argmax(diff))  # NaN counts as the maximum
        return tuple(int(i) for i in np.unravel_index(flat, diff.shape))
