"""Warp-wide votes and a reconvergence point for the core's loops (CUDA: the lanes of a warp now at
the call, or all of them; CPU: the calling thread alone, nothing). They change when a lane does its
work, never what it computes."""

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


WARP_SIZE = 32  # lanes of a CUDA warp

_SYNC = """
#if defined(__CUDA_ARCH__)
__syncwarp();
#endif
"""


@wp.func_native(_SYNC)
def sync_lanes():
    """CUDA: wait until every lane of the warp has reached this call as often as this one (`__syncwarp`),
    so that lanes split by earlier branches run on together; every lane must make the same number of
    calls. CPU: nothing."""
    ...


_HERE = """
#if defined(__CUDA_ARCH__)
return (int)__activemask();
#else
return 1;
#endif
"""


@wp.func_native(_HERE)
def lanes_here() -> wp.int32:
    """CUDA: the mask of the warp's lanes now at this call (`__activemask`); CPU: 1."""
    ...


_MEET = """
#if defined(__CUDA_ARCH__)
__syncwarp((unsigned int)here);
#endif
"""


@wp.func_native(_MEET)
def meet(here: wp.int32):
    """CUDA: wait for the lanes of mask `here` (from `lanes_here`) to reach this call, so that lanes
    that entered a branchy call together leave it together; each of them must call it once. CPU: nothing."""
    ...


_ANY_IN = """
#if defined(__CUDA_ARCH__)
return __any_sync((unsigned int)here, flag != 0) ? 1 : 0;
#else
return flag != 0 ? 1 : 0;
#endif
"""


@wp.func_native(_ANY_IN)
def any_in(here: wp.int32, flag: wp.int32) -> wp.int32:
    """1 if `flag` is non-zero in any lane of mask `here` (from `lanes_here`), else 0; every lane of
    `here` must make the call, and they all leave it together (CUDA). CPU: this thread's flag."""
    ...
