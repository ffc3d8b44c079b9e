"""Hostile and damaged HDF5 files given to `plot`, `xdmf` and `report` (issue 24, item 8): each is
refused with exit status 2 and one line on stderr (no traceback), and nothing is written: no plot
folder, no PNG, no sidecar. The corpus is made with h5py from a small real run and sweep."""

import os
import shutil

import h5py
import numpy as np
import pytest
from helpers import cli, make_scene, paper_raw

from warp_ricochet import api
from warp_ricochet.io.inputcheck import INT32_MAX


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """A complete run file and a sweep file (sidecars removed)."""
    folder = tmp_path_factory.mktemp("good")
    raw = paper_raw(bounces=2)
    raw["shot"]["count"] = 30
    raw["output"] = {"fields": ["initial", "impact", "landing"]}
    run, sweep = folder / "run.h5", folder / "sweep.h5"
    api.run(make_scene(raw, precision="float64"), output=str(run), device="cpu")
    api.sweep(
        make_scene(raw, precision="float64"),
        {"surfaces.0.mu_s": [0.5, 0.2]},
        [("surfaces.0.mu_d", 0.9, None)],
        output=str(sweep),
        device="cpu",
    )
    for p in folder.glob("*.xmf"):
        p.unlink()
    return run, sweep


def _replace(f, path, **kwargs):
    del f[path]
    f.create_dataset(path, **kwargs)


def _poke(path, offset, data):
    with open(path, "r+b") as out:
        out.seek(offset)
        out.write(data)


def _header_offset(path, name):
    """The file offset of object `name`'s header (HDF5 1.12+ tokens: the address in the first 8 bytes)."""
    with h5py.File(path, "r") as f:
        info = h5py.h5o.get_info(f[name].id)
        return int.from_bytes(info.token[:8], "little") if hasattr(info, "token") else info.addr


def _data_offset(path, name):
    with h5py.File(path, "r") as f:
        return f[name].id.get_offset()


EDITS = {
    "huge declared shape": lambda f: _replace(
        f, "pellets/landing/range", shape=(2**40,), maxshape=(None,), chunks=(65536,), dtype="f8"
    ),
    "huge tally": lambda f: _replace(f, "progress/segment_results", shape=(2**30, 2**20), chunks=(1, 1024), dtype="f8"),
    "soft-link loop": lambda f: (
        f.__setitem__("stats/a", h5py.SoftLink("/stats/b")),
        f.__setitem__("stats/b", h5py.SoftLink("/stats/a")),
    ),
    "external link": lambda f: f.__setitem__("pellets/landing/other", h5py.ExternalLink("elsewhere.h5", "/x")),
    "text statistic": lambda f: _replace(f, "stats/pellets", data="thirty"),
    "array statistic": lambda f: _replace(f, "stats/range_mean", data=np.zeros(5)),
    "stats a dataset": lambda f: (f.__delitem__("stats"), f.__setitem__("stats", np.zeros(3))),
    "no statistics": lambda f: f.__delitem__("stats"),
    "rows 1e18": lambda f: _replace(f, "progress/rows", data=np.int64(10**18)),
    "rows -5": lambda f: _replace(f, "progress/rows", data=np.int64(-5)),
    "rows float": lambda f: _replace(f, "progress/rows", data=30.0),
    "pellets beyond int32": lambda f: _replace(f, "constants/pellets", data=np.int64(INT32_MAX + 1)),
    "short per-pellet rows": lambda f: _replace(f, "pellets/landing/range", data=np.zeros(10)),
    "wrong vector shape": lambda f: _replace(f, "pellets/landing/position", data=np.zeros((30, 2))),
    "format_version 999": lambda f: f.attrs.__setitem__("format_version", 999),
    "format_version text": lambda f: f.attrs.__setitem__("format_version", "1"),
    "not ours": lambda f: f.attrs.__setitem__("format", "something-else"),
    "kind sweep": lambda f: f.attrs.__setitem__("kind", "sweep"),
    "kind banana": lambda f: f.attrs.__setitem__("kind", "banana"),
    "complete without statistics": lambda f: f["stats/pellets"].__setitem__((), np.nan),
}
BYTES = {  # (object whose bytes are overwritten, how)
    "bad checksum": ("stats/range_mean", "header"),
    "corrupted statistic": ("stats/pellets", "data"),
}
SWEEP_EDITS = {
    "sweep without /sweep": lambda f: f.__delitem__("sweep"),
    "sweep stats of the wrong length": lambda f: _replace(f, "stats/range_mean", data=np.zeros(7)),
    "sweep point rows 1e18": lambda f: _replace(f, "runs/0001/progress/rows", data=np.int64(10**18)),
}


def _hostile(good, tmp_path, case):
    run, sweep = good
    folder = tmp_path / "in"
    folder.mkdir()
    path = folder / "bad.h5"
    shutil.copy(sweep if case in SWEEP_EDITS else run, path)
    if case in BYTES:
        name, where = BYTES[case]
        if where == "header":
            _poke(path, _header_offset(path, name) + 6, b"\xa5\x5a\xa5\x5a")
        else:
            _poke(path, _data_offset(path, name), b"\x7f\x7f\x7f\x7f\x7f\x7f\x7f\x7f")
    else:
        with h5py.File(path, "r+") as f:
            (SWEEP_EDITS | EDITS)[case](f)
    return path


@pytest.mark.parametrize("case", list(EDITS) + list(BYTES) + list(SWEEP_EDITS))
def test_every_hostile_file_is_refused_in_one_line_and_nothing_is_written(good, tmp_path, case):
    path = _hostile(good, tmp_path, case)
    before = sorted(os.listdir(path.parent))
    for argv in (["plot", path], ["plot", path, "-o", tmp_path / "plots"], ["xdmf", path], ["report", path]):
        rc, out, err = cli(argv)
        assert rc == 2, (argv[0], case, rc, err)
        assert err.count("\n") == 1 and err.startswith("warp-ricochet: error: ") and "Traceback" not in err, err
        assert sorted(os.listdir(path.parent)) == before, (argv[0], case)
        assert not (tmp_path / "plots").exists()


def test_good_files_still_plot_report_and_get_a_sidecar(good, tmp_path):
    """The checks refuse none of our own files (the corpus' sources)."""
    for source in good:
        path = tmp_path / source.name
        shutil.copy(source, path)
        assert cli(["report", path])[0] == 0
        assert cli(["xdmf", path])[0] == 0
    rc, out, err = cli(["plot", tmp_path / "run.h5", "-o", tmp_path / "plots"])
    assert rc == 0, err
    assert any(name.endswith(".png") for name in os.listdir(tmp_path / "plots"))


def test_a_plot_that_fails_while_drawn_leaves_no_folder_and_no_png(good, tmp_path, monkeypatch):
    """The PNGs are drawn in memory first: a failure in the last plot leaves nothing behind."""
    from warp_ricochet.report import plots

    def broken(fig, source):
        raise KeyError("pellets/landing/position")

    monkeypatch.setattr(plots, "PLOTS", plots.PLOTS + [plots.Plot("zzz-broken", "run", (2.0, 2.0), broken)])
    rc, _, err = cli(["plot", good[0], "-o", tmp_path / "plots"])
    assert rc == 2 and "plot failed" in err and err.count("\n") == 1
    assert not (tmp_path / "plots").exists()
