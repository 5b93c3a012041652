"""Which Pinocchio frame is a MuJoCo site's counterpart, in a model built from MJCF or from a URDF.

One rule for the load-time agreement check and the cross-check: a site pairs with a frame of a
site's kind, never with a moving joint's frame that happens to share its name.
"""

from __future__ import annotations

import pinocchio as pin


def site_frame(pm: pin.Model, name: str) -> int | None:
    """The Pinocchio frame that is MuJoCo site ``name``'s counterpart, or None.

    In this order: the OP_FRAME of that name (an MJCF site, in either Pinocchio builder); the
    FIXED_JOINT frame of that name, or the BODY frame of that name that a fixed joint welds on
    (a URDF link on a fixed joint, the URDF's site). A JOINT frame (a moving joint) or the BODY
    frame of a moving link is never a site's counterpart, whatever its name.
    """
    if pm.existFrame(name, pin.FrameType.OP_FRAME):
        return int(pm.getFrameId(name, pin.FrameType.OP_FRAME))
    if pm.existFrame(name, pin.FrameType.FIXED_JOINT):
        return int(pm.getFrameId(name, pin.FrameType.FIXED_JOINT))
    if pm.existFrame(name, pin.FrameType.BODY):
        fid = int(pm.getFrameId(name, pin.FrameType.BODY))
        if pm.frames[int(pm.frames[fid].parentFrame)].type == pin.FrameType.FIXED_JOINT:
            return fid
    return None
