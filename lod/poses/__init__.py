"""The pose table: per frame, the distinct poses of every skinned character and each drawn copy's pose slot.

Copies of a character that stand in the same pose (same clip, same time quantised to the clip's key rate or
``[lod] pose_rate``) share one slot, so the render layer's pose cache (``render/poses/cache.py``) blends each
distinct pose's joint palette once and skins each distinct pose's vertices once per frame, whatever the number
of copies. :mod:`lod.poses.table` holds the parameter, the registry of skinned representations (pose groups),
the numba assignment kernel beside its numpy reference, and :class:`lod.poses.table.PoseTable`, the frame's
result that ``DrawList.poses`` carries.
"""
from lod.poses.table import (  # noqa: F401
    KEY_RATE,
    POSE_PARAMS,
    SLOT_FLOAT,
    PoseGroup,
    PoseSet,
    PoseSharing,
    PoseTable,
    assign_slots,
    assign_slots_numpy,
    pose_source,
)
