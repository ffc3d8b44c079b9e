"""Warp-wide votes for the core's loops (CUDA: the lanes of a warp now at the call; CPU: the
calling thread alone). They change when a lane does its work, never what it computes."""

import warp as wp

_ANY = """
#if defined(__CUDA_ARCH__)
return __any_sync(__activemask(), flag != 0) ? 1 : 0;
#else
return flag != 0 ? 1 : 0;
#endif
"""


@wp.func_native(_ANY)
def any_lane(flag: wp.int32) -> wp.int32:
    """1 if `flag` is non-zero in any lane of the warp now at this call (CUDA; on the CPU: in this thread), else 0."""
    ...
