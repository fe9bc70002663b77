"""The budget the property tests share: how many examples (``ROUGHSENSE_FUZZ_EXAMPLES``), derandomised unless
``ROUGHSENSE_FUZZ_RANDOM`` is set, and the characters a number-like cell is drawn from."""
from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

EXAMPLES = int(os.environ.get("ROUGHSENSE_FUZZ_EXAMPLES", "70"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=not os.environ.get("ROUGHSENSE_FUZZ_RANDOM"),
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large])
NUMBER_CHARS = "0123456789+-.eE_ ,\t\u0661\u0967\uff11\u00a0xXinfaNty%"
