"""Session 50 call 4: T = the final branch's recording core with nothing written (claim always full), no replay."""
import sys
e = sys.argv[1]
p = f"{e}/warp_ricochet/core/replay.py"
s = open(p).read()
a = "        if not self.on or rows <= 0:\n"
assert s.count(a) == 1
open(p, "w").write(s.replace(a, "        if not self.on or rows <= 0 or __import__('os').environ.get('HACK_NOREPLAY'):\n"))
p = f"{e}/warp_ricochet/tallies/path_replay.py"
s = open(p).read()
a = "        if track.log_slot < 0:\n            return track, wp.int32(-1)\n"
assert s.count(a) == 1
open(p, "w").write(s.replace(a, "        if track.log_slot > -1000000000:\n            return track, wp.int32(-1)\n"))
