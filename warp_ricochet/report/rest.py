"""Where the pellets end (physics.until = "rest", `ends`), beside where they first land: the lines
of the run summary and of `report`, the not-finished warning, and the plot of rest against landing
distance. A pellet that is not finished is counted and shown apart, never as at rest. Needs h5py
and numpy only (matplotlib for the plot; never warp)."""

from __future__ import annotations

import math

import numpy as np

from .. import display
from ..ends import AT_REST, EMBEDDED, STATES, STOPPED

NOT_FINISHED_WARNING = (
    "warning: {count:,} pellets not finished: their budget (physics.max_impacts, physics.max_steps) ran "
    "out before they stopped; they are counted apart, never as at rest (raise the budget)"
)


def _count(x) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{int(round(x)):,}"


def _m(x, decimals: int = 3) -> str:
    """A distance (m) as printed (`display`: m, or yd with --units imperial)."""
    return "n/a" if x is None or not math.isfinite(x) else display.text(x, "m", f".{decimals}f")


def has_rest(stats) -> bool:
    """Whether a run's statistics hold where its pellets end (a run with physics.until = "rest")."""
    value = stats.get("rest_at_rest")
    return value is not None and math.isfinite(float(value))


def rest_rows(stats) -> list[tuple[str, str]]:
    """(label, value) rows of the end states and rest distances, beside the landing's (none without)."""
    if not has_rest(stats):
        return []
    g = stats.get
    return [
        ("ended at rest / embedded", f"{_count(g('rest_at_rest'))} / {_count(g('rest_embedded'))}"),
        ("ended escaped / not finished", f"{_count(g('rest_escaped'))} / {_count(g('rest_not_finished'))}"),
        ("mean rest distance", f"{_m(g('rest_distance_mean'))} (std {_m(g('rest_distance_std'))}; from the shooter)"),
        ("rest distance max / min", f"{_m(g('rest_distance_max'))} / {_m(g('rest_distance_min'))}"),
        ("mean path on surfaces", _m(g("rest_path_mean"))),
        ("mean impacts", "n/a" if not math.isfinite(g("rest_impacts_mean", math.nan)) else f"{g('rest_impacts_mean'):.3f}"),
        (
            "mean steps after landing",
            "n/a" if not math.isfinite(g("rest_steps_mean", math.nan)) else f"{g('rest_steps_mean'):.1f}",
        ),
    ]


def not_finished_line(stats) -> str | None:
    """The warning when any pellet is not finished, else None."""
    count = stats.get("rest_not_finished", 0.0)
    return NOT_FINISHED_WARNING.format(count=int(count)) if has_rest(stats) and count > 0 else None


def rest_block(stats) -> str | None:
    """`report`'s block for a run: the rows and, when any pellet is not finished, the warning."""
    rows = rest_rows(stats)
    if not rows:
        return None
    width = max(len(k) for k, _ in rows)
    lines = ['where the pellets end (physics.until = "rest"; docs/ground.md)']
    lines += [f"  {k.ljust(width)}  {v}" for k, v in rows]
    warning = not_finished_line(stats)
    return "\n".join(lines + ([warning] if warning else []))


# ------------------------------------------------------------------------------------------------ plot


def read_ends(group):
    """(landing distance, rest distance, state) of the pellets of a run group (rows read as the
    landing plots do; NaN where it did not land or did not stop), or None without rest data."""
    from . import plotdata

    rest_ds, state_ds, landing_ds = (group.get(f"pellets/{p}") for p in ("rest/position", "rest/state", "landing/position"))
    if rest_ds is None or state_ds is None or landing_ds is None:
        return None
    rows = min(plotdata.rows_final(group), plotdata.MAX_ROWS, len(rest_ds))
    scene = plotdata.scene_dict(group)
    up, shooter = plotdata._up(group), plotdata._shooter(scene)

    def distance(ds):
        offset = np.asarray(ds[:rows], dtype=np.float64) - shooter
        return np.linalg.norm(offset - np.outer(offset @ up, up), axis=1)

    return distance(landing_ds), distance(rest_ds), np.asarray(state_ds[:rows])


def draw_rest_distance(fig, group) -> bool:
    """Rest against landing distance from the shooter, a point a pellet by end state (left), and
    the survival of both distances (right: the rest distance of every pellet at rest or embedded,
    landed or not, as its quantiles count them); distances in the printed unit (`display`)."""
    ends = read_ends(group)
    if ends is None:
        return False
    landing, rest, state = ends
    k, length = display.factor("m"), display.unit("m")  # m -> the printed length unit
    landing, rest = landing * k, rest * k
    ax1, ax2 = fig.subplots(1, 2)
    stopped = np.isin(state, STOPPED) & np.isfinite(landing)
    for code, colour in ((AT_REST, "C0"), (EMBEDDED, "C2")):
        sel = stopped & (state == code)
        if sel.any():
            ax1.scatter(
                landing[sel],
                rest[sel],
                s=6,
                color=colour,
                alpha=0.6,
                edgecolors="none",
                label=f"{STATES[code]} ({int(sel.sum()):,})",
            )
    if stopped.any():
        span = [min(landing[stopped].min(), rest[stopped].min()), max(landing[stopped].max(), rest[stopped].max())]
        ax1.plot(span, span, color="grey", lw=0.8, ls="--", label="rest = landing")
        ax1.legend(loc="best", fontsize="small", markerscale=2)
    else:
        ax1.text(0.5, 0.5, "no pellet landed and stopped", ha="center", va="center", transform=ax1.transAxes)
    ax1.set_xlabel(f"landing distance from the shooter ({length})")
    ax1.set_ylabel(f"rest distance from the shooter ({length})")
    ended = np.isin(state, STOPPED) & np.isfinite(rest)  # (a pellet embedded at its first impact never lands)
    for values, name, colour in ((landing[np.isfinite(landing)], "landing", "C1"), (rest[ended], "rest", "C0")):
        if values.size:
            x = np.sort(values)
            ax2.step(x, 1.0 - np.arange(x.size) / x.size, where="post", color=colour, label=f"{name} ({x.size:,})")
    ax2.set_xlabel(f"distance from the shooter ({length})")
    ax2.set_ylabel("share of pellets at least this far")
    if ax2.get_lines():
        ax2.legend(loc="best", fontsize="small")
    others = {STATES[c]: int((state == c).sum()) for c in range(len(STATES)) if c not in STOPPED}
    fig.suptitle(
        "Where the pellets end against where they land ("
        + ", ".join(f"{name}: {n:,}" for name, n in others.items())
        + f"): {group.file.filename.rsplit('/', 1)[-1]}"
    )
    return True
