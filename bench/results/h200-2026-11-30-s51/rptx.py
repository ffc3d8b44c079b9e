import sys, re, tempfile, collections
from pathlib import Path
from types import SimpleNamespace
import warp as wp
wp.init()
from bench.air import paper_scene
from bench.path import LOG_CASES
from warp_ricochet.core.replay import replay_kernel_for
from warp_ricochet.core.kernel import ricochet_kernel_for
from warp_ricochet.spec import RunSpec
settings, _ = LOG_CASES[sys.argv[1]]
scene = paper_scene(20000, air=True, mu_s=0.5, fields=("hazard", "rest"), extra=list(settings))
spec = RunSpec.of(scene, with_output=True, device=SimpleNamespace(is_cuda=True))
k = replay_kernel_for(spec) if sys.argv[2] == "replay" else ricochet_kernel_for(spec)
folder = Path(tempfile.mkdtemp())
(ptx,) = wp.compile_aot_module(k.module, arch=90, module_dir=folder, use_ptx=True)
text = ptx.read_text()
ops = collections.Counter()
seq = []
for line in text.splitlines():
    m = re.match(r"\s*(?:@%p\d+\s+)?((?:fma|mul|add|sub|div|rcp|sqrt|neg|abs|min|max|ex2|lg2)\.[\w.]*f(?:32|64))\s", line)
    if m:
        ops[m.group(1)] += 1
        seq.append(m.group(1))
print(sorted(ops.items()))
import hashlib; print("fp sequence hash", hashlib.sha1("\n".join(seq).encode()).hexdigest()[:12], len(seq))
