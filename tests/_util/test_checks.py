"""_util/checks.py: a bound is checked where the value is read (a seed beyond 2**63 - 1 is refused before any work)."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.commands import one_error
from tests.fuzzing import EXAMPLES, FUZZ
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


@pytest.mark.slow
@settings(FUZZ, max_examples=max(200, EXAMPLES * 3))
@given(seed=st.one_of(st.integers(-5, 5), st.integers(2**63 - 3, 2**63 + 3), st.integers(0, 2**80)),
       zeros=st.integers(0, 2))
def test_every_seed_reader_bounds_a_seed_alike(seed, zeros):
    """Issue 28.14: a seed is a whole number from 0 to 2**63 - 1 (and written without leading zeros) everywhere."""
    import typer

    from roughsense._util.checks import MAX_SEED, SEED
    from roughsense.cli._common import number_option
    from roughsense.errors import ConfigError
    from roughsense.sim.specimens import parse_specimen

    text = "0" * zeros + str(seed)
    valid = 0 <= seed <= MAX_SEED and (zeros == 0 or text == "0")
    try:
        option = number_option("--seed", quantity="seed")(text)
    except (typer.BadParameter, ConfigError):
        option = None
    assert (option == seed) if valid else option is None, (text, option)
    try:
        spec = parse_specimen(f"rand:1.5:0.2:{text}").seed
    except ConfigError:
        spec = None
    assert (spec == seed) if valid else spec is None, (text, spec)
    assert SEED.accepts(seed) == (0 <= seed <= MAX_SEED)
