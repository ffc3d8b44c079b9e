"""Reading run and sweep files lazily, as xarray Datasets backed by dask (`warp_ricochet.open_run`).

`open_run(path)` opens the file with h5py (SWMR-aware, so the `.partial` of a running or killed run
opens too) and wraps each per-pellet dataset in a dask array over the h5py dataset, sliced to the
rows complete (`/progress/rows`): nothing is read until a value is asked for, and then only the
chunks it needs (`chunk_rows` pellets each, whole HDF5 chunks). Dimension names come from the layout
(`io.dimensions`), so files without dimension scales read the same. The layout is in docs/output.md.

Needs the optional extra `warp-ricochet[xarray]` (xarray, dask, pandas; h5netcdf for xarray's own
reader). Imports no warp: reading needs no device.
"""

from __future__ import annotations

import os

import h5py
import numpy as np

from ..errors import OutputError
from ..fields import FIELDS, GROUPS
from .dimensions import RUN_DIMENSIONS, XYZ, dimensions_of, field_dimensions, is_dimension
from .h5open import file_kind, rows_final
from .inputcheck import open_valid

__all__ = ["Run", "open_run", "DASK_ROWS"]

DASK_ROWS = 1 << 20  # pellets per dask chunk: 16 HDF5 chunks (io.writer.MAX_H5_CHUNK_ROWS)
LAZY_BYTES = 1 << 24  # a dataset of a small group (/hazard's map) this large is read lazily (dask)
EXTRA = "pip install 'warp-ricochet[xarray]'"


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.dtype.kind in "SO":
        return [_text(v) for v in value.tolist()]
    return value


def _imports():
    try:
        import dask.array
        import xarray
    except ImportError as exc:
        raise ImportError(f"warp_ricochet.open_run needs xarray and dask ({exc.name} is missing): {EXTRA}") from None
    return xarray, dask.array


def _variable(ds: h5py.Dataset, dims, data=None):
    xr, _ = _imports()
    attrs = {
        k: _text(ds.attrs[k])
        for k in ("units", "description", "columns", "ci_low", "ci_high", "ci_method", "states")
        if k in ds.attrs
    }
    if data is None:
        data = ds[()]
        if ds.dtype.kind in "SO":  # text (the hazard thresholds' names and kinds, the site's CRS)
            data = np.asarray(_text(data if ds.ndim == 0 else np.asarray(data, dtype=object)), dtype=str)
    return xr.Variable(dims, data, attrs=attrs)


class Run:
    """One run's results, lazily: a Dataset per per-pellet group (`initial`, `impact`, `landing`,
    `collisions`, `release`, `hazard`; those the run wrote), `stats`, `constants`, `frames` (H5MD
    trajectory frames, when written) and `hazard_results` (/hazard: thresholds, danger distances and
    the map as `thresholds_name`, `danger_distance_distance`, `map_count`, ...; empty without
    `[hazard]`). Per-pellet Datasets hold the rows complete only (`rows`) and are dask backed;
    `stats`, `constants` and `hazard_results` are read at once (a map over LAZY_BYTES lazily). A sweep file without `point` has
    `stats` per point (dimension `point`, the swept values as coordinates) and no per-pellet groups.
    Keep it open while computing (a context manager; `close()`)."""

    def __init__(self, path, *, point: int | None = None, chunk_rows: int = DASK_ROWS):
        xr, _ = _imports()
        self.path = os.fspath(path)
        self.file = open_valid(self.path, f"open_run path = {self.path!r}")
        try:
            self.attrs = {k: _text(v) for k, v in self.file.attrs.items()}
            kind = self.attrs.get("kind")
            if file_kind(self.attrs) is None:
                raise OutputError(
                    f"open_run path = {self.path!r}: is not a warp-ricochet run or sweep file "
                    f"(format = {self.attrs.get('format')!r}, kind = {kind!r})"
                )
            self.points = 0
            if kind == "sweep":
                self.points = len(self.file["runs"]) if "runs" in self.file else 0
            group = self._group(point, kind)
            self.attrs.update({k: _text(v) for k, v in group.attrs.items()})
            self.status = self.attrs.get("status")
            self.pellets = int(group["constants/pellets"][()]) if "constants/pellets" in group else 0
            self.rows = rows_final(group, refresh=True)  # (first the count, then the datasets)
            self.groups = {}
            pellets = group.get("pellets", {})
            for name in GROUPS:
                if name in pellets:
                    self.groups[name] = self._pellet_group(pellets[name], name, chunk_rows)
            self.constants = self._small(group.get("constants"), "constants")
            self.hazard_results = self._small(group.get("hazard"), "hazard")
            self.stats = self._stats(group, sweep=kind == "sweep" and point is None)
            self.frames = self._frames(group.get("particles/pellets/position"), chunk_rows)
        except BaseException:
            self.file.close()
            raise

    def _group(self, point, kind) -> h5py.Group:
        if point is None or kind == "run":
            if point is not None:
                raise OutputError(f"open_run point = {point!r}: {self.path!r} is a run file, not a sweep")
            return self.file
        if not 0 <= point < self.points:
            raise OutputError(f"open_run point = {point!r}: the sweep {self.path!r} has points 0 to {self.points - 1}")
        return self.file[f"runs/{point:04d}"]

    def _pellet_group(self, g: h5py.Group, group: str, chunk_rows: int):
        xr, da = _imports()
        variables = {}
        for name, ds in g.items():
            if f"{group}.{name}" not in FIELDS:
                continue
            ds.refresh()
            dims = field_dimensions(f"{group}.{name}")
            data = da.from_array(ds, chunks=(max(1, chunk_rows),) + ds.shape[1:], lock=True, name=False)
            variables[name] = _variable(ds, dims, data[: self.rows])
        return xr.Dataset(variables, coords=self._xyz(variables), attrs=self._dataset_attrs(group))

    def _frames(self, g, chunk_rows: int):
        if g is None:
            return None
        xr, da = _imports()
        variables = {}
        for name, ds in g.items():
            ds.refresh()
            dims = RUN_DIMENSIONS[f"particles/pellets/position/{name}"]
            data = da.from_array(ds, chunks=(1,) + ds.shape[1:], lock=True, name=False) if name == "value" else ds[()]
            variables[name] = _variable(ds, dims, data)
        return xr.Dataset(variables, coords=self._xyz(variables), attrs=self._dataset_attrs("frames"))

    def _small(self, g, where: str):
        """A Dataset of the (small) datasets of `g` and its subgroups, read at once."""
        xr, da = _imports()
        if not isinstance(g, h5py.Group):
            return xr.Dataset()
        variables = {}

        def visit(path, ds):
            if isinstance(ds, h5py.Dataset) and not is_dimension(ds):
                dims = dimensions_of(f"{where}/{path}", ds)
                lazy = ds.ndim and ds.size * ds.dtype.itemsize > LAZY_BYTES
                data = da.from_array(ds, chunks="auto", lock=True, name=False) if lazy else None
                variables[path.replace("/", "_")] = _variable(ds, dims, data)

        g.visititems(visit)
        return xr.Dataset(variables, coords=self._xyz(variables), attrs=self._dataset_attrs(where))

    def _stats(self, group, *, sweep: bool):
        xr, _ = _imports()
        stats = group.get("stats", {})
        if not sweep:  # the scalars (the landing tallies' groups below /stats are arrays: docs/hazard.md), and
            # in a run of several shots each statistic's per-shot values as shots_<name> (dimension shot)
            variables = {name: _variable(ds, ()) for name, ds in stats.items() if isinstance(ds, h5py.Dataset)}
            variables.update(
                {f"shots_{name}": _variable(ds, ("shot",)) for name, ds in stats.get("shots", {}).items() if not is_dimension(ds)}
            )
            return xr.Dataset(variables, attrs=self._dataset_attrs("stats"))
        # the swept values as coordinates: a vector key's (point, xyz)
        coords = {key: _variable(ds, ("point", "xyz")[: ds.ndim]) for key, ds in self.file.get("sweep", {}).items()}
        variables = {name: _variable(ds, ("point",)) for name, ds in stats.items()}
        attrs = self._dataset_attrs("stats")
        if "sweep" in self.file:
            attrs.update({k: _text(v) for k, v in self.file["sweep"].attrs.items()})
        return xr.Dataset(variables, coords={**coords, **self._xyz(coords)}, attrs=attrs)

    def _dataset_attrs(self, group: str) -> dict:
        return {"source": f"{self.path}: {group}", "status": str(self.status), "rows": self.rows}

    @staticmethod
    def _xyz(variables) -> dict:
        return {"xyz": list(XYZ)} if any("xyz" in v.dims for v in variables.values()) else {}

    def __getattr__(self, name):
        if name in GROUPS:
            groups = self.__dict__.get("groups", {})
            if name in groups:
                return groups[name]
            raise AttributeError(
                f"{name}: this run wrote no per-pellet {name} fields (output.fields; it has {sorted(groups) or 'none'})"
            )
        raise AttributeError(name)

    def __getitem__(self, name):
        return self.groups[name]

    def dataframe(self, group: str = "landing", pellets=slice(None)):
        """The per-pellet group `group` as a pandas DataFrame of the rows `pellets` (a slice; all
        by default, read at once): one row per pellet (per pellet and ricochet for `impact`), vectors
        as columns `NAME_x`, `NAME_y`, `NAME_z`; the columns' units in `.attrs["units"]`."""
        xr, _ = _imports()
        ds = getattr(self, group).isel(pellet=pellets)
        columns, units = {}, {}
        for name, var in ds.data_vars.items():
            parts = [(f"{name}_{c}", var.sel(xyz=c, drop=True)) for c in XYZ] if "xyz" in var.dims else [(name, var)]
            for column, part in parts:
                columns[column] = part.drop_attrs() if hasattr(part, "drop_attrs") else part
                units[column] = var.attrs.get("units", "")
        frame = xr.Dataset(columns).to_dataframe()
        frame.attrs["units"] = units
        return frame

    def to_datatree(self):
        """All of it as one xarray DataTree: /pellets/<group>, /stats, /constants, /hazard, /frames."""
        xr, _ = _imports()
        tree = {f"/pellets/{name}": ds.drop_vars("xyz", errors="ignore") for name, ds in self.groups.items()}
        tree.update(
            {
                "/stats": self.stats,
                "/constants": self.constants.drop_vars("xyz", errors="ignore"),
                "/hazard": self.hazard_results.drop_vars("xyz", errors="ignore"),
            }
        )
        if self.frames is not None:
            tree["/frames"] = self.frames.drop_vars("xyz", errors="ignore")
        root = xr.Dataset(coords={"xyz": list(XYZ)}, attrs=self.attrs)
        return xr.DataTree.from_dict({"/": root, **tree})

    def close(self):
        self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return (
            f"<warp_ricochet Run {self.path!r}: status {self.status!r}, {self.rows} of {self.pellets} pellets "
            f"complete, groups {sorted(self.groups)}>"
        )


def open_run(path, *, point: int | None = None, chunk_rows: int = DASK_ROWS) -> Run:
    """Open a run file (or its `.partial`, while it runs or after it stopped) lazily; see `Run`.
    `point`: a sweep point's run (its /runs/NNNN); `chunk_rows`: pellets per dask chunk."""
    return Run(path, point=point, chunk_rows=chunk_rows)
