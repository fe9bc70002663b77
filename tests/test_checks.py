"""_util/checks.py: a bound is checked where the value is read (a seed beyond 2**63 - 1 is refused before any work)."""
from __future__ import annotations

import pytest

from tests.commands import one_error
from tests.sweeps import SWEEP


@pytest.mark.parametrize("args, message", [
    (["--seed", "9223372036854775808"], "--seed must be at most 9223372036854775807"),
    (["--seed", "1e23"], "--seed must be at most 9223372036854775807, got 1e+23"),
])
def test_a_seed_is_bounded_where_it_is_read(run_cli, tmp_path, args, message):
    """28.14: seeds >= 2**63 ended in ArrowInvalid or OverflowError after the work they seeded."""
    line = one_error(run_cli, "simulate", "--out", tmp_path / "s", "--specimens", "R3", *args)
    assert message in line
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP.format(seed=2**63, spec='"R4"'))
    line = one_error(run_cli, "explore", sweep, "--out", tmp_path / "x")
    assert "[sweep] seeds: expected a whole number from 0 to 9223372036854775807" in line
