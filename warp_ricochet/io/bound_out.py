"""A bounded run's settings and outcome in its run file: /hazard/bound (docs/hazard.md, "Running
until the answer is bounded"; `warp_ricochet.bound`). Made with the run (SWMR: no objects later),
the settings at once, the outcome at its end, when /constants/pellets becomes the pellets run.

The settings `threshold` and `fraction` are stored as `threshold_name` and `p`: /hazard holds the
dimensions `threshold` and `fraction` (`io.dimensions`), and netCDF readers (h5netcdf, so xarray's
open_datatree) take a dataset of a dimension's name in that group or below for its coordinate: a
scalar there cannot be read ("Illegal slicing argument for scalar dataspace")."""

from __future__ import annotations

import numpy as np

from .tally_out import _ds

STORED = {"threshold": "threshold_name", "fraction": "p"}  # setting -> its dataset (files before: the setting's name)


def create(group, bound) -> None:
    """/hazard/bound with the settings of `bound` (scene.schema.Bound) and the outcome's datasets
    (NaN, 0 or false until the run ends)."""
    g = group.require_group("hazard").create_group("bound")
    g.attrs["description"] = (
        "the run went on, adding shots, until the 95% interval of the danger distance of `threshold_name` at "
        "`p` was finite and narrower than `width`, or until `max_pellets` (hazard.bound)"
    )
    _ds(
        g,
        STORED["threshold"],
        np.bytes_(bound.threshold),
        unit="",
        doc="the threshold whose danger distance is bounded (hazard.bound.threshold)",
    )
    doc = "p: the share of the pellets above the threshold left beyond it (hazard.bound.fraction)"
    _ds(g, STORED["fraction"], np.float64(bound.fraction), unit="1", doc=doc)
    _ds(g, "width", np.float64(bound.width), unit="m", doc="the 95% interval's ci_high - ci_low had to be below this")
    _ds(g, "max_pellets", np.int64(bound.max_pellets), unit="1", doc="the budget: the run stops at the last whole shot within it")
    _ds(
        g,
        "met",
        np.bool_(False),
        unit="",
        doc="true: the bound was met; false: the budget was spent and the answer is not bounded",
    )
    _ds(g, "pellets", np.int64(0), unit="1", doc="pellets run (whole shots of shot.count; = /constants/pellets)")
    _ds(g, "shots", np.int64(0), unit="1", doc="shots run (pellets / shot.count)")
    _ds(g, "checks", np.int64(0), unit="1", doc="checks made (the last decided: warp_ricochet.bound)")
    _ds(g, "distance", np.float64(np.nan), unit="m", doc="the danger distance at the last check")
    _ds(g, "ci_low", np.float64(np.nan), unit="m", doc="lower end of its 95% interval at the last check")
    _ds(g, "ci_high", np.float64(np.nan), unit="m", doc="upper end of its 95% interval at the last check (inf: unbounded)")
    _ds(g, "final_width", np.float64(np.nan), unit="m", doc="ci_high - ci_low at the last check")


def write(group, result) -> None:
    """The outcome (`bound.BoundResult`) into /hazard/bound, and the pellets run into /constants/pellets."""
    g = group["hazard/bound"]
    for name in ("met", "pellets", "shots", "checks", "distance", "ci_low", "ci_high", "final_width"):
        g[name][()] = getattr(result, name)
    group["constants/pellets"][()] = result.pellets


def read(group) -> dict | None:
    """{name: value} of /hazard/bound, the settings by their keys (`threshold`, `fraction`: also in
    files written before they were stored as STORED); None when the run had no bound."""
    if "hazard/bound" not in group:
        return None
    out = {name: ds[()] for name, ds in group["hazard/bound"].items()}
    for key, name in STORED.items():
        if name in out:
            out[key] = out.pop(name)
    out["threshold"] = out["threshold"].decode()
    return out
