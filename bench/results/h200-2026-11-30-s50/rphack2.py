"""Session 50 call 3 hacks on copies of RP (after rphack.py): L = records row-major (a pellet's column
contiguous: slot * 512 + j); T = nothing recorded (claim gives -1: the recording core's work without its writes)."""
import sys
e, kind = sys.argv[1], sys.argv[2]
p = f"{e}/warp_ricochet/tallies/path_replay.py"
s = open(p).read()
if kind == "L":
    for a in ("        return tally.steps[j * tally.log_threads + slot]\n", "        tally.steps[j * tally.log_threads + slot] = value\n"):
        assert s.count(a) == 1, a
        s = s.replace(a, a.replace("j * tally.log_threads + slot", "slot * 512 + j"))
if kind == "T":
    a = "        if track.log_slot < 0:\n            return track, wp.int32(-1)\n"
    assert s.count(a) == 1
    s = s.replace(a, "        if track.log_slot > -1000000000:\n            return track, wp.int32(-1)\n")
open(p, "w").write(s)
