"""Hazard plots (PNG, matplotlib: `pip install warp-ricochet[plot]`), from a run file (an open h5py
File or Group of a run) or from the same arrays in a dict (`read_plot_data`'s keys):

- `plot_map`: landings per square metre on the map's surface (log colour scale), the contour of
  where landings above each threshold occur, and each threshold's danger distance (the smallest p
  the run can answer) as a circle around the shooter;
- `plot_survival`: the share of landed pellets at or beyond each distance from the shooter, all of
  them and those above each threshold, on a log scale, with the danger distances marked.

`draw_map(fig, source)` and `draw_survival(fig, source)` draw the same on a given matplotlib Figure
and return False when the run has nothing to draw: `warp-ricochet plot` (`report.plots`) calls them.
Lengths are drawn in the printed unit (`display`: m, or yd with --units imperial; densities per
m^2 or ft^2); the data stay SI. What the numbers mean: docs/hazard.md.
"""

from __future__ import annotations

import numpy as np

from .. import display


def _figure(size):
    try:
        from matplotlib.figure import Figure
    except ImportError:  # an optional dependency
        raise ImportError("the hazard plots need matplotlib: pip install warp-ricochet[plot]") from None
    return Figure(figsize=size, dpi=120, layout="constrained")


def _colours(n):
    from matplotlib import colormaps

    return colormaps["viridis"](np.linspace(0.15, 0.85, max(n, 1)))


def read_plot_data(group) -> dict:
    """The arrays the plots use, from a run file's group (a dict is returned as it is)."""
    if isinstance(group, dict):
        return group
    if "stats/histograms" not in group:
        return {}
    from ..tallies.bins import ROW_DISTANCE

    h = group.get("hazard")
    levels = len(h["thresholds/name"]) + 1 if h is not None and "thresholds" in h else None
    counts = group["stats/histograms/counts"][()]  # (then, with thresholds, each one's reach: not landings)
    out = {
        "edges": group["stats/histograms/edges"][()],
        "distance_counts": counts[ROW_DISTANCE : None if levels is None else ROW_DISTANCE + levels],
    }
    if h is not None and "thresholds" in h:
        danger = "landing_danger_distance" if "landing_danger_distance" in h else "danger_distance"  # the landings'
        out.update(
            names=[n.decode() for n in h["thresholds/name"][()]],
            threshold_speed=h["thresholds/speed"][()],
            fractions=h[f"{danger}/fraction"][()],
            danger_distance=h[f"{danger}/distance"][()],
            ci_low=h[f"{danger}/ci_low"][()],
            ci_high=h[f"{danger}/ci_high"][()],
        )
        if "map" in h:
            m = h["map"]
            out.update({f"map_{k}": m[k][()] for k in ("count", "above", "energy", "u_edges", "v_edges", "outside")})
            if "exposure" in m and danger == "landing_danger_distance":  # along the path (docs/hazard.md 11)
                out.update(
                    map_passes=m["passes"][()],
                    map_exposure=m["exposure"][()],
                    map_passes_outside=int(m["exposure_outside"][0]),
                    reach_distance=h["danger_distance/distance"][()],
                    reach_ci_high=h["danger_distance/ci_high"][()],
                )
    return out


def _survival(counts, total):
    """Share of `total` at or beyond each bin's lower edge."""
    return np.cumsum(np.asarray(counts)[::-1])[::-1] / total


def plot_survival(source, path, title="Landings beyond a distance from the shooter"):
    """The survival curve of the distance, all landings and above each threshold; writes `path`."""
    fig = _figure((7, 4.5))
    if not draw_survival(fig, source, title):
        raise ValueError("the run has no landing histograms (output.quantiles = false)")
    fig.savefig(path)


def _same(arrays) -> list[list[int]]:
    """Indices of `arrays` grouped by equal content, in first-seen order (curves that would coincide)."""
    groups: dict = {}
    for i, a in enumerate(arrays):
        groups.setdefault(np.asarray(a).tobytes(), []).append(i)
    return list(groups.values())


def draw_survival(fig, source, title="Landings beyond a distance from the shooter") -> bool:
    """The survival curve on `fig`; False when the run counted no landings (output.quantiles off).
    Thresholds whose curves coincide (every landing above all of them) are one curve named by all;
    the danger-distance lines are in the legend only when drawn."""
    from matplotlib.lines import Line2D

    d = read_plot_data(source)
    if "distance_counts" not in d:
        return False
    by_level = np.asarray(d["distance_counts"], dtype=np.int64)
    total = by_level.sum()
    k = display.factor("m")  # m -> the printed length unit
    edges = np.asarray(d["edges"], dtype=np.float64) * k
    ax = fig.subplots()
    styles = set()  # the line styles of the danger distances drawn (one legend entry each)
    if total:
        all_counts = by_level.sum(axis=0)
        used = np.flatnonzero(all_counts)
        lo, hi = used[0], used[-1] + 1
        x = edges[lo : hi + 1]
        s = np.append(_survival(all_counts, total)[lo:hi], 0.0)
        ax.step(x, np.maximum(s, 1e-12), where="post", color="k", label="all landings")
        names = d.get("names", [])
        order = np.argsort(d.get("threshold_speed", []), kind="stable")
        above = np.cumsum(by_level[::-1], axis=0)[::-1]
        colours = _colours(len(names))
        counts = {index: above[position + 1] for position, index in enumerate(order)}
        shown = [i for i in order if counts[i].sum()]
        for group in _same([np.concatenate([counts[i], d["danger_distance"][i]]) for i in shown]):
            index = shown[group[0]]
            same = all_counts.tolist() == counts[index].tolist()
            label = "above " + ", ".join(names[shown[g]] for g in group) + (" (every landing)" if same else "")
            s = np.append(_survival(counts[index], total)[lo:hi], 0.0)
            dashes = (0, (6, 3)) if same else "-"  # dashed over the black curve it hides otherwise
            ax.step(x, np.maximum(s, 1e-12), where="post", color=colours[index], label=label, ls=dashes)
            for j, p in enumerate(d["fractions"]):
                r = d["danger_distance"][index, j]
                if np.isfinite(r):
                    style = ":" if j else "--"
                    ax.axvline(r * k, color=colours[index], ls=style, lw=0.8)
                    styles.add((j, style, p))
        ax.set_yscale("log")
        ax.set_ylim(max(0.5 / total, 1e-12), 1.5)
    ax.set_xlabel(f"horizontal distance from the shooter ({display.unit('m')})")
    ax.set_ylabel("share of landed pellets at or beyond")
    ax.set_title(title + (f" ({total:,} landed)" if total else " (none landed)"), fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    for _j, style, p in sorted(styles):  # one entry a line style, for the lines drawn in it
        handles.append(Line2D([], [], color="0.3", ls=style, lw=0.8))
        labels.append(f"danger distance, p = {p:g}")
    if handles:
        ax.legend(handles, labels, fontsize=8)
    return True


def plot_map(source, path, title="Landings on the map"):
    """The hazard map: landings per m^2, contours of landings above each threshold, danger
    distances as circles around the shooter (u, v) = (0, 0); writes `path`."""
    d = read_plot_data(source)
    fig = _figure(_map_size(d) if "map_count" in d else (8, 6))
    if not draw_map(fig, d, title):
        raise ValueError("the run has no hazard map ([hazard] map_cell and map_extent)")
    fig.savefig(path)


def _map_size(d, entries=None) -> tuple[float, float]:
    """Inches that fit the grid's shape (6.5 inches wide), the title, the axis label and a legend
    line per entry (default: per threshold)."""
    u, v = d["map_u_edges"], d["map_v_edges"]
    aspect = (v[-1] - v[0]) / (u[-1] - u[0])
    entries = len(d.get("names", [])) if entries is None else entries
    return 8.0, min(9.0, max(1.2, 6.5 * aspect)) + 1.0 + 0.16 * (entries + 1)


def draw_map(fig, source, title="Landings on the map") -> bool:
    """The hazard map on `fig` (a constrained layout, resized to the grid's shape); False when the
    run has no map. Thresholds with the same landings above them share one contour and entry; the
    shooter, at (u, v) = (0, 0), is marked when inside the map."""
    from matplotlib.colors import LogNorm

    d = read_plot_data(source)
    if "map_count" not in d:
        return False
    what, outside = "landings", d.get("map_outside", 0)
    if "map_passes" in d:  # along the path: the passes within body height, the reach's danger distances
        d = {
            **d,
            "map_count": d["map_passes"],
            "map_above": d["map_exposure"],
            "danger_distance": d["reach_distance"],
            "ci_high": d["reach_ci_high"],
        }
        what, outside, title = "passes", d["map_passes_outside"], "Passes within body height on the map"
    k, length = display.factor("m"), display.unit("m")  # m -> the printed length unit
    u, v, count = np.asarray(d["map_u_edges"]) * k, np.asarray(d["map_v_edges"]) * k, d["map_count"]
    area = display.value((d["map_u_edges"][1] - d["map_u_edges"][0]) * (d["map_v_edges"][1] - d["map_v_edges"][0]), "m^2")
    names = d.get("names", [])
    layers = [
        np.concatenate([(d["map_above"][i] > 0).ravel(), d["danger_distance"][i], d["ci_high"][i]]) for i in range(len(names))
    ]
    groups = _same(layers)
    fig.set_size_inches(*_map_size(d, len(groups)))
    ax = fig.subplots()
    density = np.where(count > 0, count / area, np.nan)
    if np.isfinite(density).any():
        mesh = ax.pcolormesh(u, v, density, norm=LogNorm(), cmap="Greys", shading="flat")
        aspect = (v[-1] - v[0]) / (u[-1] - u[0])  # the axes keep equal scales: a flat grid, a short bar
        per = display.unit("m^2").replace("^2", "$^2$")
        fig.colorbar(mesh, ax=ax, label=f"{what} per {per}", shrink=min(1.0, max(0.3, 1.6 * aspect)))
    colours = _colours(len(groups))
    uc, vc = 0.5 * (u[1:] + u[:-1]), 0.5 * (v[1:] + v[:-1])
    angle = np.linspace(0, 2 * np.pi, 361)
    for colour, group in zip(colours, groups):
        i, name = group[0], ", ".join(names[g] for g in group)
        layer = d["map_above"][i]
        contour = layer.max() > 0 and min(layer.shape) > 1
        if contour:
            ax.contour(uc, vc, (layer > 0).astype(float), levels=[0.5], colors=[colour], linewidths=1.0)
        bounded = np.flatnonzero(np.isfinite(d["ci_high"][i]))  # the smallest p this run can answer
        if layer.max() == 0:
            label = f"{name}: none above"
        elif len(bounded):
            j = bounded[np.argmin(d["fractions"][bounded])]
            r = d["danger_distance"][i, j] * k
            ax.plot(r * np.cos(angle), r * np.sin(angle), color=colour, ls="--", lw=0.8)
            label = f"danger distance {r:.4g} {length} (p = {d['fractions'][j]:g})"
            label = f"{name}: where above; dashed: {label}" if contour else f"{name}: {label}"
        else:
            label = f"{name}: where above (too few {what} for a danger distance)"
        ax.plot([], [], color=colour, label=label)
    if u[0] <= 0 <= u[-1] and v[0] <= 0 <= v[-1]:
        ax.plot([0], [0], marker="*", color="C3", ls="", label="shooter")
    ax.set_xlim(u[0], u[-1])
    ax.set_ylim(v[0], v[-1])
    ax.set_aspect("equal")
    ax.set_xlabel(f"u: downrange from the shooter ({length})")
    ax.set_ylabel(f"v: cross-range ({length})")
    ax.set_title(f"{title} ({int(count.sum()):,} in the grid, {int(outside):,} outside)", fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        fig.legend(fontsize=7, loc="outside lower center", frameon=False, ncol=2)
    return True
