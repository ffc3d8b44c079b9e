import csv, sys, collections
def load(fn):
    rows = {}
    f = None
    with open(fn) as fh:
        for r in csv.reader(fh):
            if not r: continue
            if r[0] == "File Path": f = r[1].split("/")[-1]; continue
            if r[0] in ("Function Name", "Line No"): continue
            if r[0] and r[0] != "":
                try: ln = int(r[0])
                except: continue
                def num(x):
                    try: return float(x)
                    except: return 0.0
                rows[(f, ln)] = dict(src=r[1][:110], samples=num(r[4]), inst=num(r[7]), thr=num(r[8]))
    return rows
m = load(sys.argv[1]); 
tot_i = sum(v["inst"] for v in m.values()); tot_t = sum(v["thr"] for v in m.values()); tot_s = sum(v["samples"] for v in m.values())
print(f"total warp inst {tot_i:.3e} thread {tot_t:.3e} lanes {tot_t/tot_i:.2f} samples {tot_s:.0f}")
byfile = collections.defaultdict(lambda: [0,0,0])
for (f, ln), v in m.items():
    byfile[f][0] += v["inst"]; byfile[f][1] += v["thr"]; byfile[f][2] += v["samples"]
for f, (i, t, s) in sorted(byfile.items(), key=lambda kv: -kv[1][0])[:20]:
    print(f"{f:40s} inst {100*i/tot_i:5.1f}%  thr {100*t/tot_t:5.1f}%  lanes {t/max(i,1):5.2f}  samples {100*s/tot_s:5.1f}%")
key = sys.argv[2] if len(sys.argv) > 2 else "inst"
print("--- top lines by", key)
for (f, ln), v in sorted(m.items(), key=lambda kv: -kv[1][key])[:int(sys.argv[3]) if len(sys.argv)>3 else 40]:
    print(f"{f[:22]:22s}:{ln:4d} inst {100*v['inst']/tot_i:5.2f}% lanes {v['thr']/max(v['inst'],1):5.2f} samp {100*v['samples']/tot_s:5.2f}% | {v['src'].strip()[:90]}")
