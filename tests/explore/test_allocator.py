"""A Dask worker's frozen malloc thresholds are reset before a cell runs (explore/allocator.py)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, resource
import numpy as np
from roughsense.explore.allocator import relax_frozen_malloc_thresholds

def faults():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(200):
        a = np.ones(1 << 17)  # 1 MiB: above the frozen 128 KiB mmap threshold, below the relaxed one
        del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

frozen = faults()
relaxed = relax_frozen_malloc_thresholds()
print(json.dumps({"frozen": frozen, "relaxed": relaxed, "after": faults()}))
"""


def _probe(env_extra: dict) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**env, **env_extra}, capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_dasks_trim_setting_is_undone_and_big_arrays_stop_faulting_in_fresh_pages():
    seen = _probe({"MALLOC_TRIM_THRESHOLD_": "65536"})  # what Dask's nanny gives its workers
    assert seen["relaxed"] is True
    # frozen: every 1 MiB array is a new mapping, 256 pages faulted in each time; relaxed: the heap reuses them
    assert seen["frozen"] > 200 * 200
    assert seen["after"] < seen["frozen"] / 20


def test_a_process_whose_thresholds_are_its_own_is_left_alone():
    assert _probe({})["relaxed"] is False
