"""The frames both engines compare, and the Jacobian entries worth comparing.

:func:`match_frames` pairs the robot's MuJoCo bodies and sites with the Pinocchio frames of the
same names and of their kind (:func:`site_frame`): a body with a BODY frame; a site with an
OP_FRAME, else with a frame a fixed joint welds on (a URDF has no sites: its idiom is a link on a
fixed joint, which Pinocchio's parser makes a FIXED_JOINT frame and a BODY frame), never with the
frame of a moving joint or of a moving link that shares its name (aloha's finger sites and joints).

Pinocchio's frame Jacobians are formed per chunk of states the way Pinocchio forms them
(:func:`frame_jacobians`), because Pinocchio has no call for many frames and 50 calls per state
cost more than the rest of its work: for LOCAL_WORLD_ALIGNED the columns of the joints that
support the frame with the linear rows shifted to the frame's origin, ``v_F = v_O - p_WF x w``
(``getFrameJacobian``); the test suite checks it against that function.

The Jacobians are most of the data (G1: 50 frames x 6 x 35 per state and engine) but mostly
zeros: a column is non-zero only for the joints that move the frame. Both engines write exact
zeros elsewhere (Pinocchio outside the joint's support, :func:`support_mask`; MuJoCo's ``mj_jac``
outside the body's dof chain, :func:`mj_support_mask`), so only the union of the two supports is
kept, packed (:func:`jacobian_packing`; 31 % of the entries on the G1), which gives the same
maxima as the full arrays.

:func:`joint_placements_view` reads all of Pinocchio's joint placements with one copy per state.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.model_pair import Robot
from mbctl.robots.site_frames import site_frame


class Frames(NamedTuple):
    """The compared frames: bodies then sites that both engines have, by name.

    Attributes:
        pin_ids: Pinocchio frame ids (nf,), bodies first.
        mj_body_ids: MuJoCo body ids of the body frames.
        mj_site_ids: MuJoCo site ids of the site frames.
        names: Frame names (nf,).
        missing: MuJoCo bodies and sites without a Pinocchio frame of their name and kind, in words.
    """

    pin_ids: list[int]
    mj_body_ids: np.ndarray
    mj_site_ids: np.ndarray
    names: list[str]
    missing: list[str]


def match_frames(robot: Robot) -> Frames:
    """The robot's MuJoCo bodies and sites paired with the Pinocchio frames of the same names and kind.

    A body pairs with the BODY frame of its name, a site with :func:`site_frame`; joints pair with
    joints by name elsewhere (``robots/joint_pairing.py``), never with a body or site.
    """
    pm = robot.pin_model
    pin_ids, body_ids, site_ids, names, missing = [], [], [], [], []
    for b, name in zip(robot.robot_body_ids, robot.bodies, strict=True):
        if name and pm.existFrame(name, pin.FrameType.BODY):
            pin_ids.append(pm.getFrameId(name, pin.FrameType.BODY))
            body_ids.append(b)
            names.append(name)
        else:
            missing.append(f"body {name or f'#{b}'}")
    for s, name in zip(robot.robot_site_ids, robot.sites, strict=True):
        fid = site_frame(pm, name) if name else None
        if fid is None:
            missing.append(f"site {name or f'#{s}'}")
            continue
        pin_ids.append(fid)
        site_ids.append(s)
        names.append(name)
    return Frames(pin_ids, np.array(body_ids, dtype=int), np.array(site_ids, dtype=int), names, missing)


def support_mask(pm: pin.Model, frame_ids: list[int]) -> np.ndarray:
    """(nf, nv) ones on the velocity coordinates of the joints that move each frame, else zeros."""
    mask = np.zeros((len(frame_ids), pm.nv))
    for k, f in enumerate(frame_ids):
        for j in pm.supports[pm.frames[f].parentJoint]:
            if j > 0:
                mask[k, pm.idx_vs[j] : pm.idx_vs[j] + pm.nvs[j]] = 1.0
    return mask


def mj_support_mask(robot: Robot, m: mujoco.MjModel, frames: Frames) -> np.ndarray:
    """(nf, nv) ones on the robot's velocity coordinates in each frame's MuJoCo dof chain."""
    robot_col = {int(p): k for k, p in enumerate(np.arange(m.nv)[robot.qvel_index])}
    bodies = [int(b) for b in frames.mj_body_ids] + [int(m.site_bodyid[s]) for s in frames.mj_site_ids]
    mask = np.zeros((len(bodies), robot.nv))
    for k, b in enumerate(bodies):
        while b > 0 and m.body_dofnum[b] == 0:  # the nearest body at or above b with dofs
            b = int(m.body_parentid[b])
        dof = int(m.body_dofadr[b] + m.body_dofnum[b] - 1) if b > 0 else -1
        while dof >= 0:
            if dof in robot_col:
                mask[k, robot_col[dof]] = 1.0
            dof = int(m.dof_parentid[dof])
    return mask


def jacobian_packing(union: np.ndarray, free_v: list[int]
                     ) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """The order of the compared Jacobian entries (frame, column) of ``union`` (nf, nv).

    Each free joint's linear columns come first, as three runs (x, y, z) over the same frames, so
    that ``T`` acts on contiguous blocks (``VelocityMaps.right_packed``); then every other entry.

    Returns:
        Frame (L,) and column (L,) of each entry, and per free joint (start, number of frames).
    """
    union = union.copy()
    frames: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    blocks: list[tuple[int, int]] = []
    for iv in free_v:
        f = np.flatnonzero(union[:, iv : iv + 3].any(axis=1))
        blocks.append((int(sum(x.size for x in frames)), int(f.size)))
        for i in range(3):
            frames.append(f)
            cols.append(np.full(f.size, iv + i))
        union[:, iv : iv + 3] = False
    rest_f, rest_c = np.nonzero(union)
    frames.append(rest_f)
    cols.append(rest_c)
    return np.concatenate(frames).astype(int), np.concatenate(cols).astype(int), blocks


def frame_jacobians(J_world: np.ndarray, p_WF: np.ndarray, mask: np.ndarray, out: np.ndarray) -> np.ndarray:
    """LOCAL_WORLD_ALIGNED frame Jacobians from Pinocchio's world-frame joint Jacobians.

    Args:
        J_world: ``data.J`` of each state (c, 6, nv): spatial velocity at the world origin.
        p_WF: Frame origins in the world (c, nf, 3) [m].
        mask: ``support_mask`` (nf, nv).
        out: Where to write (c, nf, 6, nv).

    Returns:
        ``out``: rows 0-2 the velocity of each frame's origin, rows 3-5 its angular velocity.
    """
    np.multiply(J_world[:, None], mask[None, :, None, :], out=out)
    lin, ang = out[:, :, :3], out[:, :, 3:]
    p = p_WF[..., None]  # (c, nf, 3, 1)
    # v_F = v_O + w x p_WF = v_O - p_WF x w, column by column (as Evaluator._packed_pin does)
    for a, b, e in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        lin[:, :, a] -= p[:, :, b] * ang[:, :, e]
        lin[:, :, a] += p[:, :, e] * ang[:, :, b]
    return out


def joint_placements_view(data: pin.Data) -> np.ndarray | None:
    """A read-only view (njoints, 4, 3) of ``data.oMi``: per joint the columns of ``[R_WJ | p_WJ]``.

    Pinocchio hands out each placement as a new SE3 and a new array (0.4 us per joint, 12 us of a
    cross-check state on the G1). Its element references are live views into ``data.oMi``, one
    contiguous std::vector, so one strided view reads every placement in one copy. The layout is
    checked element by element (rotation column-major, translation after it, one stride); None
    when it differs. Valid while ``data`` lives (Pinocchio's algorithms never resize ``oMi``).
    """
    refs = [data.oMi[j] for j in range(len(data.oMi))]
    rot, trans = [r.rotation for r in refs], [r.translation for r in refs]
    at = np.array([[x.__array_interface__["data"][0] for x in rot],
                   [x.__array_interface__["data"][0] for x in trans]], dtype=np.int64)
    stride = int(at[0, 1] - at[0, 0]) if len(refs) > 1 else 96
    if (any(x.strides != (8, 24) or x.dtype != np.float64 for x in rot)
            or any(x.strides != (8,) or x.dtype != np.float64 for x in trans)
            or np.any(np.diff(at[0]) != stride) or np.any(at[1] - at[0] != 72)
            or stride < 96 or stride % 8):
        return None
    n = len(refs)
    flat = np.lib.stride_tricks.as_strided(rot[0], shape=(n, 12), strides=(stride, 8), writeable=False)
    return flat.reshape(n, 4, 3)

