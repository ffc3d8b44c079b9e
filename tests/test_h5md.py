"""The trajectory frames against the H5MD 1.1.0 specification's required elements
(https://www.nongnu.org/h5md/h5md.html, releases/h5md-1.1.0, and its units module 1.0.0), checked
element by element from the spec's text, and once with MDAnalysis' H5MDReader where it is installed."""

import h5py
import numpy as np
import pytest
from helpers import make_scene, paper_raw

from warp_ricochet import api

PELLETS = 30


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    raw = paper_raw()
    raw["shot"]["count"] = PELLETS
    raw["collisions"] = {"enabled": True, "frame_every": 8}
    path = tmp_path_factory.mktemp("h5md") / "frames.h5"
    api.run(make_scene(raw, precision="float64"), output=str(path), device="cpu")
    return path


def _attr_type(obj, name):
    """(HDF5 type class, is variable-length string, dataspace shape) of attribute `name`."""
    attr = h5py.h5a.open(obj.id, name.encode())
    t = attr.get_type()
    vlen = isinstance(t, h5py.h5t.TypeStringID) and t.is_variable_str()
    return t.get_class(), vlen, attr.shape


def _fixed_string(obj, name, shape=()):
    """`String[]` with the spec's "fixed-length string datatype" (of `shape`)."""
    cls, vlen, space = _attr_type(obj, name)
    assert cls == h5py.h5t.STRING and not vlen and space == shape, (obj.name, name)
    value = obj.attrs[name]
    return value.decode("ascii") if shape == () else [v.decode("ascii") for v in value]


def _integer(obj, name, shape):
    cls, _, space = _attr_type(obj, name)
    assert cls == h5py.h5t.INTEGER and space == shape, (obj.name, name)
    return obj.attrs[name]


def _unit(ds):
    """units module: `unit` is a scalar variable-length ASCII string of unit factors."""
    cls, vlen, space = _attr_type(ds, "unit")
    assert cls == h5py.h5t.STRING and vlen and space == ()
    assert h5py.h5a.open(ds.id, b"unit").get_type().get_cset() == h5py.h5t.CSET_ASCII
    return ds.attrs["unit"]


def test_h5md_metadata(frames):
    """`h5md` (the one mandatory root group): version Integer[2] = [1, 1]; author with name
    String[]; creator with name and version String[]; modules/units with version [1, 0] and
    system (scalar, variable-length string)."""
    with h5py.File(frames) as f:
        h5md = f["h5md"]
        assert list(_integer(h5md, "version", (2,))) == [1, 1]
        assert _fixed_string(h5md["author"], "name")
        assert _fixed_string(h5md["creator"], "name") == "warp-ricochet"
        assert _fixed_string(h5md["creator"], "version")
        units = h5md["modules/units"]
        assert list(_integer(units, "version", (2,))) == [1, 0]
        cls, vlen, space = _attr_type(units, "system")
        assert cls == h5py.h5t.STRING and vlen and space == () and units.attrs["system"] == "SI"


def test_particles_group(frames):
    """Every subgroup of `particles` holds `box` with dimension Integer[] and boundary String[D]
    of "periodic"/"none" (all "none": `edges` may be left out); `position` is a time-dependent
    element: step Integer[variable] and time Float[variable], both increasing, value
    [variable][N][D] with the particle index second; species and id Integer[N], ids unique."""
    with h5py.File(frames) as f:
        assert list(f["particles"]) == ["pellets"]
        g = f["particles/pellets"]
        box = g["box"]
        dim = int(_integer(box, "dimension", ()))
        assert dim == 3
        assert _fixed_string(box, "boundary", (dim,)) == ["none"] * 3
        assert "edges" not in box  # allowed: all boundaries "none"
        pos = g["position"]
        step, time, value = pos["step"], pos["time"], pos["value"]
        assert step.dtype.kind == "i" and step.ndim == 1 and step.maxshape == (None,)
        assert time.dtype.kind == "f" and time.shape == step.shape
        assert value.dtype.kind == "f" and value.shape == (step.shape[0], PELLETS, dim)
        assert step.shape[0] > 1
        assert np.all(np.diff(step[()]) > 0) and np.all(np.diff(time[()]) > 0)
        assert _unit(value) == "m" and _unit(time) == "s"
        for name in ("species", "id"):
            ds = g[name]
            assert ds.dtype.kind == "i" and ds.shape == (PELLETS,), name
        assert len(np.unique(g["id"][()])) == PELLETS
        np.testing.assert_array_equal(value[0], f["pellets/initial/position"][()])  # id = row in /pellets


def test_mdanalysis_reads_the_frames(frames):
    """MDAnalysis' H5MDReader knows molecular lengths only (A, nm, pm, fm): our "m" needs one
    entry in its table, then it reads every frame, positions and times as stored."""
    pytest.importorskip("MDAnalysis")
    from MDAnalysis.coordinates.H5MD import H5MDReader

    with pytest.raises(RuntimeError, match="length unit 'm'"):
        H5MDReader(str(frames))
    table = H5MDReader._unit_translation["length"]
    added = "m" not in table
    table.setdefault("m", "m")
    try:
        reader = H5MDReader(str(frames), convert_units=False)
        with h5py.File(frames) as f:
            pos = f["particles/pellets/position"]
            assert reader.n_frames == pos["step"].shape[0] and reader.n_atoms == PELLETS
            for k in (0, reader.n_frames - 1):
                ts = reader[k]
                np.testing.assert_allclose(ts.positions, pos["value"][k], rtol=1e-6)  # MDAnalysis keeps float32
                assert ts.time == pos["time"][k] and ts.data["step"] == pos["step"][k]
        reader.close()
    finally:
        if added:
            table.pop("m")
