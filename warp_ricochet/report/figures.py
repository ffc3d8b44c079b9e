"""Drawing functions for the plots: each takes matplotlib Axes and NumPy arrays (SI units) and draws
one view. `plots` assembles them into figures from run files; other plots (hazard maps, thresholds)
can reuse them. Needs numpy and matplotlib (the `plot` extra).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "landing_map",
    "range_histogram",
    "survival_curve",
    "energy_distance",
    "sweep_band",
    "nice_step",
    "plain_log",
    "SCATTER_MAX",
]

SCATTER_MAX = 20_000  # up to this many points are drawn one by one; more as binned densities
SURVIVAL_POINTS = 4_000  # points of a drawn survival curve (the tail's ranks are kept exactly)


def nice_step(span: float, bins: int) -> float:
    """A round bin width (1, 2 or 5 times a power of ten) giving about `bins` bins over `span`."""
    raw = max(span, 1e-12) / max(bins, 1)
    power = 10.0 ** math.floor(math.log10(raw))
    return next(m * power for m in (1, 2, 5, 10) if m * power >= raw)


def plain_log(ax, axis: str = "x") -> None:
    """A logarithmic axis with plain numbers (50, 2, 0.01) and minor labels at 2 and 5 times a power."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    def label(v, _pos):
        return f"{v:g}"

    def minor(v, _pos):
        if v <= 0:
            return ""
        lead = round(v / 10.0 ** math.floor(math.log10(v)), 6)
        return f"{v:g}" if lead in (2.0, 5.0) else ""

    target = ax.xaxis if axis == "x" else ax.yaxis
    (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
    lo, hi = ax.get_xlim() if axis == "x" else ax.get_ylim()
    if 0 < lo < hi < 5 * lo:  # under a factor 5 (e.g. 120 ... 172 m), powers and 2, 5 times them are too far apart
        from matplotlib.ticker import MaxNLocator, NullFormatter

        target.set_major_locator(MaxNLocator(nbins=6))
        target.set_major_formatter(FuncFormatter(label))
        target.set_minor_formatter(NullFormatter())
        return
    target.set_major_locator(LogLocator(base=10))
    target.set_major_formatter(FuncFormatter(label))
    target.set_minor_formatter(FuncFormatter(minor))


def _norm(values):
    """A colour scale for positive `values`: logarithmic when they span more than a factor 20."""
    from matplotlib.colors import LogNorm, Normalize

    finite = values[np.isfinite(values) & (values > 0)]
    if finite.size == 0:
        return Normalize()
    lo, hi = float(finite.min()), float(finite.max())
    return LogNorm(lo, hi) if hi > 20 * lo else Normalize(lo, hi if hi > lo else lo * 1.001 + 1e-12)


def _planes(ax, planes, shooter, up, e1, e2):
    """Non-horizontal planes as the line where each meets the horizontal through its point; horizontal
    planes named in the legend, and the other kinds (plates, boxes, posts, meshes, terrain: finite or
    not flat, so no line) by their kind."""
    for i, (name, point, normal, kind) in enumerate(planes):
        if kind != "plane":
            ax.plot([], [], " ", label=f"{name}: {kind} (surface {i}, not drawn)")
            continue
        n = normal / np.linalg.norm(normal)
        t = np.cross(up, n)
        if np.linalg.norm(t) < 1e-6:  # horizontal: the ground, seen face on
            height = float((point - shooter) @ up)
            where = f"{abs(height):.3g} m {'below' if height < 0 else 'above'} the shooter" if height else "at the shooter"
            ax.plot([], [], " ", label=f"{name}: horizontal plane {where}")
            continue
        p = point - shooter
        xy = (float(p @ e1), float(p @ e2))
        ax.axline(
            xy, (xy[0] + float(t @ e1), xy[1] + float(t @ e2)), color=f"C{i % 10}", lw=2, ls="--", label=f"{name} (plane {i})"
        )


def _edges(values, bins: int):
    """Round bin edges covering `values`, about `bins` of them."""
    step = nice_step(float(np.ptp(values)) or 1.0, bins)
    return np.arange(math.floor(values.min() / step), math.floor(values.max() / step) + 2) * step


def landing_map(ax_overview, ax_zoom, landings, e1, e2, axis_names=("e1", "e2")):
    """Where pellets land, seen from above, shooter at the origin. `ax_overview` (to scale, with the
    shooter and the planes): each landing coloured by its kinetic energy (J), or the mean energy per
    cell above SCATTER_MAX pellets. `ax_zoom`: the landing zone, landings per m^2 in cells."""
    rel = landings.position - landings.shooter
    x, y = rel @ e1, rel @ e2
    n, energy = x.size, landings.energy
    labels = (f"downrange, along {axis_names[0]} (m)", f"cross-range, along {axis_names[1]} (m)")
    ax_overview.plot([0], [0], marker="*", ms=16, color="crimson", mec="k", ls="", label="shooter", zorder=5)
    _planes(ax_overview, landings.planes, landings.shooter, landings.up, e1, e2)
    ax_overview.set_aspect("equal", adjustable="datalim")
    for ax in (ax_overview, ax_zoom):
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        ax.grid(alpha=0.3)
    ax_overview.set_title(f"To scale, shooter at the origin ({n:,} landed)")
    if n == 0:
        return
    bins = int(np.clip(math.sqrt(n) / 2, 8, 100))
    if energy is None:
        ax_overview.scatter(x, y, s=4, color="k", label="landings")
    elif n <= SCATTER_MAX:
        order = np.argsort(energy)
        art = ax_overview.scatter(
            x[order], y[order], c=energy[order], s=6 if n > 2000 else 12, cmap="inferno", norm=_norm(energy), edgecolors="none"
        )
        ax_overview.figure.colorbar(art, ax=ax_overview, label="kinetic energy at landing (J)")
    else:
        cell = nice_step(max(float(np.ptp(x)), float(np.ptp(y))), bins)
        xb = np.arange(math.floor(x.min() / cell), math.floor(x.max() / cell) + 2) * cell
        yb = np.arange(math.floor(y.min() / cell), math.floor(y.max() / cell) + 2) * cell
        counts, _, _ = np.histogram2d(x, y, bins=(xb, yb))
        sums, _, _ = np.histogram2d(x, y, bins=(xb, yb), weights=energy)
        mean = np.ma.masked_invalid(np.where(counts > 0, sums / np.maximum(counts, 1), np.nan).T)
        art = ax_overview.pcolormesh(xb, yb, mean, cmap="inferno", norm=_norm(mean.compressed()))
        ax_overview.figure.colorbar(art, ax=ax_overview, label=f"mean kinetic energy at landing (J), {cell:g} m cells")
    ax_overview.legend(loc="best", fontsize="small", framealpha=0.8)
    xb, yb = _edges(x, bins), _edges(y, bins)
    counts, _, _ = np.histogram2d(x, y, bins=(xb, yb))
    dx, dy = xb[1] - xb[0], yb[1] - yb[0]
    density = np.ma.masked_equal(counts.T / (dx * dy), 0)
    mesh = ax_zoom.pcolormesh(xb, yb, density, cmap="viridis", norm=_norm(density.compressed()))
    ax_zoom.figure.colorbar(mesh, ax=ax_zoom, label=f"landings per m$^2$ ({dx:g} m x {dy:g} m cells)")
    if n <= 2000:
        ax_zoom.scatter(x, y, s=3, color="w", alpha=0.7, edgecolors="none")
    ax_zoom.set_title("The landing zone: density of landings (not to scale)")


def range_histogram(ax, values, label="range (m)"):
    """Counts of `values` in round bins."""
    values = values[np.isfinite(values)]
    if values.size == 0:
        return
    span = float(np.ptp(values))
    bins = int(np.clip(np.sqrt(values.size), 10, 120))
    if span > 0:
        step = nice_step(span, bins)
        edges = np.arange(math.floor(values.min() / step), math.floor(values.max() / step) + 2) * step
    else:
        edges = np.array([values[0] - 0.5, values[0] + 0.5])
    ax.hist(values, bins=edges, color="C0", alpha=0.85)
    ax.yaxis.set_major_formatter(lambda v, _pos: f"{v:,.0f}")
    ax.set_xlabel(label)
    ax.set_ylabel("pellets per bin" + (f" ({edges[1] - edges[0]:g} m)" if span > 0 else ""))
    ax.grid(alpha=0.3)


def survival_curve(ax, values, label=None, color=None):
    """P(X >= x) of `values` against x on a log scale, down to 1/n, so the tail shows."""
    values = np.sort(values[np.isfinite(values)])
    n = values.size
    if n == 0:
        return
    ranks = np.arange(n)
    if n > SURVIVAL_POINTS:  # geometric in the tail's rank, so the last pellets stay visible
        tail = n - np.unique(np.geomspace(1, n, SURVIVAL_POINTS).astype(np.int64))
        ranks = np.unique(np.concatenate([tail, [0, n - 1]]))
    ax.step(values[ranks], (n - ranks) / n, where="post", label=label, color=color)
    plain_log(ax, "y")
    ax.yaxis.set_minor_formatter(lambda v, _pos: "")
    ax.set_ylim(0.5 / n, 1.5)
    ax.set_ylabel("fraction of pellets at least this far")
    ax.grid(alpha=0.3)
    ax.grid(alpha=0.1, which="minor")


def energy_distance(ax, distance, energy, slipped=None):
    """Kinetic energy at landing (J) against horizontal distance from the shooter (m); stick and slip
    (first impact) in two colours below SCATTER_MAX points, else a log-count density."""
    keep = np.isfinite(distance) & np.isfinite(energy)
    distance, energy = distance[keep], energy[keep]
    if distance.size == 0:
        return
    log = energy.min() > 0 and energy.max() > 10 * energy.min()
    if distance.size <= SCATTER_MAX:
        size = 6 if distance.size > 2000 else 14
        if slipped is not None:
            slipped = slipped[keep]
            for value, name, colour in ((0, "stuck at the first impact", "C0"), (1, "slipped at the first impact", "C1")):
                sel = slipped == value
                if sel.any():
                    ax.scatter(
                        distance[sel],
                        energy[sel],
                        s=size,
                        color=colour,
                        alpha=0.6,
                        edgecolors="none",
                        label=f"{name} ({int(sel.sum()):,})",
                    )
            ax.legend(loc="best", fontsize="small", markerscale=2)
        else:
            ax.scatter(distance, energy, s=size, alpha=0.6, edgecolors="none")
        if log:
            plain_log(ax, "y")
    else:
        art = ax.hexbin(distance, np.log10(energy) if log else energy, gridsize=80, bins="log", mincnt=1, cmap="viridis")
        ax.figure.colorbar(art, ax=ax, label="pellets per cell")
        if log:  # log10 of the energy binned: ticks at whole decades, labelled in J
            from matplotlib.ticker import FuncFormatter, MaxNLocator

            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
            ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{10**v:.3g}"))
    ax.set_xlabel("horizontal distance from the shooter to the landing point (m)")
    ax.set_ylabel("kinetic energy at landing (J)")
    ax.grid(alpha=0.3, which="both")


PAPER_NOTE = (
    "Zohdi (2021), Table 3: <L> and L- to L+;\nits rows with sticking pellets (mu_s >= 0.05) do not\n"
    "follow from its eqs. (27)-(29), whose 5/7 v_t we\ndraw: docs/paper-reproduction.md"
)


def sweep_band(ax, x, mean, low, high, label=None, color=None, paper=None):
    """A swept statistic: `mean` against `x` with the band from `low` to `high` (L- to L+);
    `paper`: optional (x, mean, low, high) of the paper's rows, drawn as markers with error bars."""
    order = np.argsort(x)
    x, mean, low, high = (np.asarray(a, dtype=np.float64)[order] for a in (x, mean, low, high))
    (line,) = ax.plot(x, mean, marker="o", ms=4, label=f"mean range <L>, {label}" if label else "mean range <L>", color=color)
    ax.fill_between(
        x,
        low,
        high,
        alpha=0.25,
        color=line.get_color(),
        label=f"shortest to longest, L- to L+, {label}" if label else "shortest to longest, L- to L+",
    )
    if paper is not None and len(paper[0]):
        px, pm, plo, phi = (np.asarray(a, dtype=np.float64) for a in paper)
        ax.errorbar(px, pm, yerr=[pm - plo, phi - pm], fmt="s", color="k", mfc="none", ms=6, capsize=3, label=PAPER_NOTE)
    ax.grid(alpha=0.3)
