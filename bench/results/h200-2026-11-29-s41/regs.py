import sys, time, tomllib, ctypes
from pathlib import Path
import warp_ricochet as wr
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.core.kernel import ricochet_kernel_for
from warp_ricochet.spec import RunSpec
root = Path.cwd(); n = int(float(sys.argv[1]))
raw = tomllib.loads((root / "examples" / "hazard.toml").read_text())
raw["shot"]["shots"] = max(1, n // 280)
raw["physics"] = {**raw["physics"], "until": "rest"}
raw["output"] = {"fields": []}
raw.pop("hazard")
post = {"name": "post", "kind": "cylinder", "point": [20.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "radius": 0.1, "length": 1.2, "material": "concrete"}
cuda = ctypes.CDLL("libcuda.so.1")
for label, surf in (("post", raw["surfaces"] + [post]),):
    sc = scene_from_dict({**raw, "surfaces": surf})
    wr.run(sc, None, device="cuda:0")
    ts = []
    for _ in range(3):
        t = time.perf_counter(); s = wr.run(sc, None, device="cuda:0"); ts.append(time.perf_counter() - t)
    kernel = ricochet_kernel_for(RunSpec.of(sc, with_output=False))
    att = []
    for ex in kernel.module.execs.values():
        hooks = ex.get_kernel_hooks(kernel)
        vals = []
        for a in (4, 3):
            v = ctypes.c_int(0); cuda.cuFuncGetAttribute(ctypes.byref(v), a, ctypes.c_void_p(hooks.forward)); vals.append(v.value)
        att.append(tuple(vals))
    print(f"{root.name} {label}: runs {[round(x*1e3) for x in ts]} ms for {raw['shot']['shots']*280} pellets, {s['rest_steps_mean']:.2f} steps; (registers, local bytes) {att}", flush=True)
