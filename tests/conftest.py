"""Shared test configuration: a deterministic hypothesis profile and a CLI runner."""
from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "roughsense",
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "roughsense"))


@pytest.fixture
def run_cli(capsys):
    """Run ``roughsense ARGS`` in-process; returns (exit_code, stdout, stderr)."""
    from roughsense.cli import main

    def _run(*args: str):
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return _run
