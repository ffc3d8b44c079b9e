"""Results are bitwise those recorded in tests/data/golden-cpu.json (tests/golden.py): every per-pellet
dataset and statistic of the paper's scene, the steel plate, a spinning multi-plane scene and collision
runs in both precisions."""

import json

import pytest

from tests import golden


def _recorded():
    if not golden.GOLDEN.exists():
        return None
    return json.loads(golden.GOLDEN.read_text())


@pytest.mark.parametrize("case", sorted(golden.CASES))
def test_results_are_bitwise_the_recorded_ones(case, tmp_path):
    data = _recorded()
    assert data is not None, "tests/data/golden-cpu.json is missing: python -m tests.golden record"
    if data["fingerprint"] != golden.fingerprint():
        pytest.skip(f"digests recorded on {data['fingerprint']!r}, this is {golden.fingerprint()!r}: "
                    "record this machine's with python -m tests.golden record (on code known to be right)")
    got = golden.run_case(case, tmp_path)
    want = data["cases"][case]
    assert sorted(got) == sorted(want), sorted(set(got) ^ set(want))
    changed = [name for name in want if got[name] != want[name]]
    assert not changed, f"{len(changed)} datasets changed: {changed[:8]}"
