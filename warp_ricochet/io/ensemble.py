"""An ensemble's intervals and per-shot values in a run file (`tallies.ensemble`).

Each `/stats/<name>` of a run of several shots carries attributes `ci_low` and `ci_high` (its 95%
interval over shots, NaN until the run ends) and `ci_method`; `/stats/shots/<name>` holds one value
per shot, in shot order. All are made when the run starts (a file in SWMR mode takes no new objects
later) and filled at its end.
"""

import h5py
import numpy as np

from ..tallies.ensemble import CI_METHOD, STAT_KIND, Ensemble
from ..tallies.sums import STAT_UNITS


def create_ensemble_datasets(group: h5py.Group, stats, shots: int) -> None:
    """The interval attributes on `group/stats/<name>` and the datasets `group/stats/shots/<name>`."""
    per_shot = group.require_group("stats/shots")
    per_shot.attrs["shots"] = shots
    per_shot.attrs["description"] = "each statistic of each shot alone, in shot order (tallies.ensemble)"
    for name in stats:
        ds = group[f"stats/{name}"]
        ds.attrs["ci_low"] = np.nan
        ds.attrs["ci_high"] = np.nan
        ds.attrs["ci_method"] = CI_METHOD[STAT_KIND[name]]
        values = per_shot.create_dataset(name, shape=(shots,), maxshape=(None,), dtype="f8", fillvalue=np.nan)
        values.attrs["units"], values.attrs["description"] = STAT_UNITS[name]


def write_ensemble(group: h5py.Group, ensemble: Ensemble) -> None:
    """Fill what `create_ensemble_datasets` made (attributes modified in place), the per-shot
    datasets cut to the shots run (a bounded run's are made for its budget)."""
    group["stats/shots"].attrs.modify("shots", ensemble.shots)
    for name, values in ensemble.per_shot.items():
        ds = group[f"stats/{name}"]
        ds.attrs.modify("ci_low", np.float64(ensemble.low[name]))
        ds.attrs.modify("ci_high", np.float64(ensemble.high[name]))
        group[f"stats/shots/{name}"].resize((len(values),))
        group[f"stats/shots/{name}"][:] = values


def read_ensemble(stats_group: h5py.Group):
    """name -> (ci_low, ci_high) of a run's /stats (empty when it has no intervals)."""
    return {
        name: (float(ds.attrs["ci_low"]), float(ds.attrs["ci_high"]))
        for name, ds in stats_group.items()
        if isinstance(ds, h5py.Dataset) and "ci_low" in ds.attrs
    }
