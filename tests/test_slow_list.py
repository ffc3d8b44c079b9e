"""tests/slow.txt names tests that exist: a renamed or removed slow test would otherwise leave a
stale line, and its new name would run in CI unnoticed."""

import re
from pathlib import Path

TESTS = Path(__file__).parent


def test_every_slow_node_id_names_a_test_function_that_exists():
    stale = []
    for line in (TESTS / "slow.txt").read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        path, _, name = line.partition("::")
        function = re.sub(r"\[.*\]$", "", name)
        source = TESTS.parent / path
        if not source.is_file() or not re.search(rf"^def {re.escape(function)}\(", source.read_text(), re.MULTILINE):
            stale.append(line)
    assert not stale, "tests/slow.txt names tests that do not exist:\n" + "\n".join(stale)
