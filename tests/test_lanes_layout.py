"""How many threads share a statistics segment (`spec.RunSpec.lanes`, `tallies.reduce`): costly
pellets (followed to rest; against a terrain or a large mesh) get REST_LANES threads of 16 pellets,
so a GPU has work for all its multiprocessors from 1e6 pellets; the statistics stay bitwise the
same for any chunk size."""

import numpy as np
import pytest
from helpers import paper_raw

import warp_ricochet as wr
from warp_ricochet.scene import scene_from_dict
from warp_ricochet.spec import RunSpec
from warp_ricochet.tallies.reduce import LANES, REST_LANES

RIGID = {"restitution": 0.01, "mu_s": 0.5, "mu_d": 0.45}


def terrain_raw(tmp_path, count, until="landing"):
    """The paper's shot over a 120 x 80 raster of gentle waves (0.5 m cells), a plane 5 m below."""
    pytest.importorskip("rasterio", reason="the gis extra (rasterio) is not installed")
    from test_terrain import write_tif

    east, north = 0.5 * np.arange(120)[None, :], 0.5 * np.arange(80)[:, None]
    path = write_tif(tmp_path / "waves.tif", 0.2 * np.sin(east / 3.0) * np.cos(north / 2.0), 0.0, 0.0, 0.5)
    raw = paper_raw(until=until)
    raw["shot"]["count"] = count
    raw["surfaces"] = [
        {"kind": "terrain", "file": str(path), "origin": [5.0, -20.0], **RIGID},
        {"point": [0.0, -5.0, 0.0], "normal": [0.0, 1.0, 0.0], **RIGID},
    ]
    return raw


def test_costly_scenes_get_many_threads_of_few_pellets(tmp_path):
    assert RunSpec.of(scene_from_dict(paper_raw(until="landing"))).lanes == LANES
    assert RunSpec.of(scene_from_dict(paper_raw(until="rest"))).lanes == REST_LANES
    assert RunSpec.of(scene_from_dict(terrain_raw(tmp_path, 10))).lanes == REST_LANES
    box = paper_raw(until="landing")
    box["surfaces"].append(
        {
            "kind": "box",
            "point": [3.0, 0.5, 0.0],
            "normal": [0.0, 1.0, 0.0],
            "axis_u": [1.0, 0.0, 0.0],
            "size": [1.0, 1.0, 1.0],
            **RIGID,
        }
    )
    assert RunSpec.of(scene_from_dict(box)).lanes == LANES  # a small mesh: its triangles tested whole


def test_a_terrain_run_s_statistics_are_bitwise_the_same_for_any_chunk_size(tmp_path):
    """Three 65,536-pellet segments in one chunk and one a chunk: the same statistics to the bit."""
    raw = terrain_raw(tmp_path, 3 * 65_536 - 100)
    raw["output"] = {"fields": []}
    stats = []
    for numerics in ({}, {"chunk_size": 65_536}):
        raw["numerics"] = {**raw.get("numerics", {}), **numerics}
        stats.append(wr.run(scene_from_dict(raw), device="cpu"))
    assert stats[0]["hits"] > 0
    for key, value in stats[0].items():
        assert repr(value) == repr(stats[1][key]), key
