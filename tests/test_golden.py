"""Results are bitwise those recorded in tests/data/golden-cpu.json (tests/golden.py): every per-pellet
dataset and statistic of the paper's scene, the steel plate, a spinning multi-plane scene and collision
runs in both precisions. A statistic added after the recording (a new name under /stats) is allowed;
a recorded dataset that is gone, or a per-pellet dataset that was not recorded, fails."""

import pytest

from tests import golden


@pytest.mark.parametrize("case", sorted(golden.CASES))
def test_results_are_bitwise_the_recorded_ones(case, tmp_path):
    machines = golden.recorded()
    assert machines, "tests/data/golden-cpu.json is missing: python -m tests.golden record"
    here = golden.fingerprint()
    if here not in machines:
        pytest.skip(
            f"no digests recorded on {here!r} (only on {sorted(machines)}): record this machine's "
            "with python -m tests.golden record, on code known to be right"
        )
    if case not in machines[here]:
        pytest.skip(
            f"no digests of {case!r} recorded on {here!r} (its results changed on purpose since: "
            "record them with python -m tests.golden record, on code known to be right)"
        )
    got = golden.run_case(case, tmp_path)
    want = machines[here][case]
    missing = sorted(set(want) - set(got))
    assert not missing, f"{len(missing)} recorded datasets are gone: {missing[:8]}"
    # a statistic added since the recording is new, not changed: every recorded one is still compared
    added = sorted(set(got) - set(want))
    assert all(name.startswith("stats/") for name in added), f"per-pellet datasets not recorded: {added[:8]}"
    changed = [name for name in want if got[name] != want[name]]
    assert not changed, f"{len(changed)} datasets changed: {changed[:8]}"
