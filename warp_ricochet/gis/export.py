"""`warp-ricochet export`: a run's danger-area outlines as GeoJSON and its map layers as a GeoTIFF
(docs/hazard.md, "Outlines and GIS files"). Everything is checked, then computed, then written (each
file whole or not at all)."""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import dataclass

import h5py
import numpy as np
import shapely

from ..errors import OutputError, RicochetError, not_regular
from ..io.atomic import replaced
from .outline import outline, to_multipolygon
from .site import Georeference

LOCAL_NOTE = "local engineering coordinates, metres: u downrange along the line of fire, v cross-range (to its left), the shooter at (0, 0)"
LOCAL_WKT = (
    'ENGCRS["warp-ricochet local map (u downrange, v cross-range to the left; metres; shooter at 0, 0)",'
    'EDATUM["the shooter projected on the map surface"],CS[Cartesian,2],'
    'AXIS["u (downrange)",east,LENGTHUNIT["metre",1]],AXIS["v (cross-range, left)",north,LENGTHUNIT["metre",1]]]'
)
INT32_MAX = np.iinfo(np.int32).max


class ExportError(RicochetError):
    """An export input or option that cannot be used (one line)."""


@dataclass
class MapData:
    """What export reads from a run file."""

    u_edges: np.ndarray
    v_edges: np.ndarray
    names: list
    kinds: list
    values: np.ndarray
    basis: str  # "exposure" or "landings"
    counts: np.ndarray  # (K, nv, nu) per threshold, of the basis
    off_grid: np.ndarray  # (K,) of the basis
    layers: dict  # GeoTIFF band description -> (nv, nu)
    fractions: np.ndarray
    pellets: int
    site: dict | None  # crs, shooter, azimuth, local

    @property
    def cell(self) -> float:
        return float(self.u_edges[1] - self.u_edges[0])


def check_fractions(fractions) -> None:
    for p in fractions:
        if not 0.0 < p < 1.0:  # (NaN fails too)
            raise ExportError(f"--p = {p!r}: must be a number in (0, 1), the share of the exposure left outside an outline")


def check_output(path, option: str, overwrite: bool) -> None:
    """Refuse an output path that is a folder or no regular file, has no folder, or exists without `overwrite`."""
    shown = f"{option} {os.fsdecode(path)!r}"
    if os.path.isdir(path):
        raise OutputError(f"{shown}: is a directory; give a file path")
    if why := not_regular(path):
        raise OutputError(f"{shown}: {why}")
    if os.path.lexists(path) and not overwrite:
        raise OutputError(f"{shown}: exists; give --overwrite to replace it")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OutputError(f"{shown}: its folder does not exist")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"{shown}: its folder is not writable")


def _text(value) -> str:
    value = value[()] if isinstance(value, h5py.Dataset) else value
    return value.decode() if isinstance(value, bytes) else str(value)


def read_map(path) -> MapData:
    """The map, thresholds and site of run file `path`; ExportError/OutputError (one line) when it has none."""
    from ..io.h5open import file_kind, rows_final
    from ..io.inputcheck import open_valid

    shown = f"export {os.fsdecode(path)!r}"
    with open_valid(path, shown) as f:
        attrs = {k: _text(v) for k, v in f.attrs.items() if k in ("kind", "format", "status")}
        if file_kind(attrs) != "run":  # (check_file let through a run or a sweep)
            raise ExportError(f"{shown}: is a sweep file; export takes a run file (run the point's scene on its own)")
        if attrs.get("status") != "complete":
            raise ExportError(f"{shown}: the run is not complete (status {attrs.get('status')!r}); export a completed run")
        if "hazard/map" not in f:
            raise ExportError(f"{shown}: has no hazard map; run the scene with hazard.map_cell and hazard.map_extent")
        m, th = f["hazard/map"], f["hazard/thresholds"]
        names = [_text(x) for x in th["name"][()]]
        kinds = [_text(x) for x in th["kind"][()]]
        layers = {"landings per cell": m["count"][()]}
        if "rest" in m:
            layers["pellets at rest per cell"] = m["rest"][()]
        if "passes" in m:
            layers["passes per cell (within body height)"] = m["passes"][()]
        above = m["above"][()]
        layers.update({f"landings above {n}": a for n, a in zip(names, above)})
        if "exposure" in m:  # passes above each threshold, their off-grid ones after all passes' (contract)
            basis, counts = "exposure", m["exposure"][()]
            off_grid = m["exposure_outside"][()][1:]
            layers.update({f"passes above {n}": a for n, a in zip(names, counts)})
        else:  # an older run: its landings above each threshold; those off the grid (or on other surfaces)
            basis, counts = "landings", above
            off_grid = th["landings"][()] - above.sum(axis=(1, 2))
        site = None
        if "hazard/site" in f:
            s = f["hazard/site"]
            site = {
                "crs": _text(s["crs"]),
                "shooter": s["shooter"][()],
                "azimuth": float(s["azimuth"][()]),
                "local": s["local"][()],
            }
        return MapData(
            u_edges=m["u_edges"][()],
            v_edges=m["v_edges"][()],
            names=names,
            kinds=kinds,
            values=th["value"][()],
            basis=basis,
            counts=counts,
            off_grid=np.asarray(off_grid, dtype=np.int64),
            layers=layers,
            fractions=f["hazard/danger_distance/fraction"][()],
            pellets=rows_final(f),
            site=site,
        )


def georeference(data: MapData) -> Georeference | None:
    if data.site is None:
        return None
    s = data.site
    try:
        return Georeference(s["crs"], s["shooter"], s["azimuth"], s["local"])
    except ValueError as exc:  # (a run file written where pyproj knew the CRS, read where it does not)
        raise ExportError(f"hazard.site.crs = {s['crs']!r}: {exc}") from None


def features(data: MapData, fractions, geo: Georeference | None) -> list[dict]:
    """One GeoJSON feature per (threshold, p), in the site's CRS (else local coordinates)."""
    u0, v0, cell = float(data.u_edges[0]), float(data.v_edges[0]), data.cell
    out = []
    for i, name in enumerate(data.names):
        for p in fractions:
            o = outline(data.counts[i], int(data.off_grid[i]), float(p), u0, v0, cell)
            geometry = o.geometry
            if geometry is not None and geo is not None:
                geometry = to_multipolygon(
                    shapely.transform(geometry, lambda xy: np.column_stack(geo.to_crs(xy[:, 0], xy[:, 1])))
                )
            props = {
                "threshold": name,
                "kind": data.kinds[i],
                "value": float(data.values[i]),
                "p": float(p),
                "basis": data.basis,
                "contained": o.contained,
                "area_m2": o.area,
                "pellets": int(data.pellets),
                "total": o.total,
                "outside": o.left_out,
                "off_grid": o.off_grid,
                "cells": o.cells,
            }
            if geo is None:
                props["crs_note"] = LOCAL_NOTE
            geom = None if geometry is None else shapely.geometry.mapping(geometry)
            out.append({"type": "Feature", "properties": props, "geometry": geom})
    return out


def crs_member(geo: Georeference | None) -> dict:
    """The GeoJSON (2008) `crs` member GDAL reads: the site CRS's URN, else the local engineering CRS."""
    if geo is None:
        name = LOCAL_WKT
    elif geo.crs.is_geographic and geo.crs.to_authority() == ("EPSG", "4326"):
        name = "urn:ogc:def:crs:OGC:1.3:CRS84"  # (longitude first, as written)
    else:
        authority, code = geo.crs.to_authority()
        name = f"urn:ogc:def:crs:{authority}::{code}"
    return {"type": "name", "properties": {"name": name}}


def geojson_text(data: MapData, fractions, geo) -> str:
    collection = {
        "type": "FeatureCollection",
        "name": "danger areas",
        "crs": crs_member(geo),
        "crs_note": LOCAL_NOTE if geo is None else f"{geo.crs.to_string()}; x first (easting or longitude)",
        "features": features(data, fractions, geo),
    }
    return json.dumps(collection, allow_nan=False)


def raster_frame(data: MapData, geo: Georeference | None):
    """(rasterio CRS, Affine, tags) of the map's raster, its first row the cells of highest v. A
    projected site: the affine through three corners mapped exactly (pyproj), its largest miss at the
    fourth corner and the centre in the tags; a geographic site: the shooter's local azimuthal
    equidistant projection (the map is exactly a rotated grid there)."""
    from rasterio.crs import CRS
    from rasterio.transform import Affine

    (u0, u1), (v0, v1) = data.u_edges[[0, -1]], data.v_edges[[0, -1]]
    nu, nv = len(data.u_edges) - 1, len(data.v_edges) - 1
    tags = {"BASIS": data.basis, "PELLETS": str(data.pellets), "CELL_M": repr(data.cell)}
    if geo is None:
        tags["CRS_NOTE"] = LOCAL_NOTE
        return CRS.from_wkt(LOCAL_WKT), Affine(data.cell, 0.0, u0, 0.0, -data.cell, v1), tags
    if geo.crs.is_geographic:
        crs, to = CRS.from_wkt(geo.aeqd.to_wkt()), geo.to_aeqd
        tags["CRS_NOTE"] = f"local azimuthal equidistant projection centred on the shooter, on the datum of {geo.crs.to_string()}"
    else:
        crs, to = CRS.from_user_input(geo.crs.to_wkt()), geo.to_crs
        tags["CRS_NOTE"] = geo.crs.to_string()
    x, y = (np.asarray(c, dtype=np.float64) for c in to([u0, u1, u0, u1, (u0 + u1) / 2], [v1, v1, v0, v0, (v0 + v1) / 2]))
    affine = Affine((x[1] - x[0]) / nu, (x[2] - x[0]) / nv, x[0], (y[1] - y[0]) / nu, (y[2] - y[0]) / nv, y[0])
    cols, rows = np.array([nu, nu / 2]), np.array([nv, nv / 2])
    ax, ay = affine.a * cols + affine.b * rows + affine.c, affine.d * cols + affine.e * rows + affine.f
    tags["AFFINE_MAX_ERROR"] = repr(float(np.max(np.hypot(ax - x[3:], ay - y[3:]))))
    tags["AZIMUTH_DEG"] = repr(data.site["azimuth"])
    return crs, affine, tags


def write_geotiff(path, data: MapData, geo) -> None:
    import rasterio

    crs, affine, tags = raster_frame(data, geo)
    layers = [np.asarray(a) for a in data.layers.values()]
    whole = all(np.issubdtype(a.dtype, np.integer) for a in layers)
    dtype = "int32" if whole and max(int(a.max(initial=0)) for a in layers) <= INT32_MAX else "float64"
    nv, nu = layers[0].shape
    profile = dict(driver="GTiff", width=nu, height=nv, count=len(layers), dtype=dtype, nodata=None, compress="deflate")
    with rasterio.open(path, "w", **profile, crs=crs, transform=affine) as out:
        out.update_tags(**tags)
        for band, (name, layer) in enumerate(zip(data.layers, layers), start=1):  # (one band at a time)
            out.write(layer[::-1].astype(dtype), band)  # (row 0: highest v)
            out.set_band_description(band, name)


def export(run, geojson=None, geotiff=None, fractions=None, overwrite: bool = False) -> list[str]:
    """Write the outlines (`geojson`) and map layers (`geotiff`) of run file `run`; the paths written.
    `fractions`: the containments p (default: the run's hazard.fractions)."""
    if geojson is None and geotiff is None:
        raise ExportError("export: give --geojson OUT.geojson and/or --geotiff OUT.tif")
    if fractions is not None:
        check_fractions(fractions)
    outputs = [(p, o) for p, o in ((geojson, "--geojson"), (geotiff, "--geotiff")) if p is not None]
    for path, option in outputs:
        check_output(path, option, overwrite)
    if len(outputs) == 2 and os.path.abspath(geojson) == os.path.abspath(geotiff):
        raise OutputError(f"--geotiff {os.fsdecode(geotiff)!r}: is the --geojson path too; give two files")
    data = read_map(run)
    geo = georeference(data)
    text = None if geojson is None else geojson_text(data, data.fractions if fractions is None else fractions, geo)
    with contextlib.ExitStack() as stack:  # (both moved into place only when both are written)
        if text is not None:
            with open(stack.enter_context(replaced(geojson)), "w") as out:
                out.write(text + "\n")
        if geotiff is not None:
            write_geotiff(stack.enter_context(replaced(geotiff)), data, geo)
    return [os.fsdecode(p) for p, _ in outputs]
