"""Nsight Compute's source counters of a kernel by file and by line of the package's Python (Warp
compiles CUDA with line information that points at the @wp.func sources): where the warp
instructions go and how many lanes were active on each, to find code whose lanes have split.

On the lent GPU (`bench/ncu_source.sh` does both steps):

    ncu -k regex:ricochet_kernel -c 1 --section WarpStateStats --section SourceCounters \\
        --import-source yes -o OUT/rep python3 -m bench.profile_map --device cuda:0 --n 1e6
    ncu -i OUT/rep.ncu-rep --page source --csv --print-source cuda,sass > OUT/source.csv

Here: `python -m bench.ncu_lines OUT/source.csv [--by inst|thr|samples] [--top 40]`. Prints the
totals (warp instructions, thread instructions, active lanes = their ratio, stall samples), the
shares by file, then the top lines. Figures: bench/RESULTS.md "Lanes that meet".
"""

from __future__ import annotations

import argparse
import collections
import csv

COLUMNS = {"samples": 4, "inst": 7, "thr": 8}  # in ncu 2025.3's source page: all samples, warp and thread instructions


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return 0.0


def read(path: str) -> dict:
    """{(file name, line): {"src", "samples", "inst", "thr"}} from the page's per-line rows."""
    rows, current = {}, None
    with open(path, newline="") as handle:
        for row in csv.reader(handle):
            if not row:
                continue
            if row[0] == "File Path":
                current = row[1].split("/")[-1]
            elif row[0].isdigit() and current is not None:
                rows[current, int(row[0])] = {"src": row[1].strip(), **{k: _number(row[i]) for k, i in COLUMNS.items()}}
    return rows


def report(rows: dict, by: str = "inst", top: int = 40) -> str:
    total = {k: sum(v[k] for v in rows.values()) or 1.0 for k in COLUMNS}
    lines = [
        f"warp instructions {total['inst']:.3e}, thread instructions {total['thr']:.3e}, "
        f"active lanes {total['thr'] / total['inst']:.2f}, stall samples {total['samples']:.0f}"
    ]
    files = collections.defaultdict(lambda: dict.fromkeys(COLUMNS, 0.0))
    for (name, _line), v in rows.items():
        for k in COLUMNS:
            files[name][k] += v[k]
    for name, v in sorted(files.items(), key=lambda kv: -kv[1]["inst"])[:20]:
        lines.append(
            f"{name:32s} inst {100 * v['inst'] / total['inst']:5.1f}%  thr {100 * v['thr'] / total['thr']:5.1f}%  "
            f"lanes {v['thr'] / max(v['inst'], 1.0):5.2f}  samples {100 * v['samples'] / total['samples']:5.1f}%"
        )
    lines.append(f"--- top {top} lines by {by}")
    for (name, line), v in sorted(rows.items(), key=lambda kv: -kv[1][by])[:top]:
        lines.append(
            f"{name[:24]:24s}:{line:5d} inst {100 * v['inst'] / total['inst']:5.2f}% lanes "
            f"{v['thr'] / max(v['inst'], 1.0):5.2f} samples {100 * v['samples'] / total['samples']:5.2f}% | {v['src'][:80]}"
        )
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m bench.ncu_lines", description=__doc__.split("\n")[0])
    parser.add_argument("csv")
    parser.add_argument("--by", choices=tuple(COLUMNS), default="inst")
    parser.add_argument("--top", type=int, default=40)
    args = parser.parse_args(argv)
    print(report(read(args.csv), args.by, args.top))


if __name__ == "__main__":
    main()
