import sys
e = sys.argv[1]
p = f"{e}/warp_ricochet/core/replay.py"
s = open(p).read()
rep = [("ORDERED = spec.collisions, any(f.startswith(\"hazard.\") for f in spec.core_fields), spec.hazard_map",
        "ORDERED = spec.collisions, any(f.startswith(\"hazard.\") for f in spec.core_fields), spec.hazard_map or bool(__import__('os').environ.get('HACK_ORDERED'))"),
       ("        if not self.on or rows <= 0:\n", "        if not self.on or rows <= 0 or __import__('os').environ.get('HACK_NOREPLAY'):\n"),
       ("            wp.launch(kernels[0], dim=rows, inputs=[rows, release, tally, reach, ints, self.overflowed], device=self.device)\n",
        "            if not __import__('os').environ.get('HACK_NOLINES'):\n                wp.launch(kernels[0], dim=rows, inputs=[rows, release, tally, reach, ints, self.overflowed], device=self.device)\n"),
       ("            wp.launch(kernels[1], dim=rows, inputs=[rows, outputs, tally, reach, ints], device=self.device)\n",
        "            if not __import__('os').environ.get('HACK_NOFLIGHTS'):\n                wp.launch(kernels[1], dim=rows, inputs=[rows, outputs, tally, reach, ints], device=self.device)\n")]
for a, b in rep:
    assert s.count(a) == 1, a
    s = s.replace(a, b)
open(p, "w").write(s)
