"""explore on a real SLURM cluster (issue 37): scripts/slurm_localhost.sh starts one on this machine, .ci/run runs
this file with ``-m slurm``. The workers run as batch jobs that dask-jobqueue submits, configured the Dask way
(``DASK_JOBQUEUE__SLURM__...``); their results must equal a LocalCluster's row for row, and no job may outlive the run.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from tests.foreground import sigint_as_in_a_terminal
from tests.sweeps import small_sweep

pytestmark = pytest.mark.slurm

SWEEP = small_sweep(range(2))
JOB_NAME = "roughsense-test"
#: Not a timing check: how long a wait on SLURM (a job to start, a cancelled one to go) may last before the test
#: fails instead of hanging.
HANG_GUARD_S = 300


def _explore(sweep: Path, out: Path, env: dict, *options: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "roughsense.cli", "explore", str(sweep), "--out", str(out), *options],
                          env=env, capture_output=True, text=True, timeout=900)


def _queued() -> list[str]:
    return subprocess.run(["squeue", "-h", "-n", JOB_NAME, "-o", "%i %t"], capture_output=True, text=True,
                          check=True).stdout.split("\n")[:-1]


def _left_queued() -> list[str]:
    """The test's jobs still queued once SLURM has ended them: ``scancel`` returns at once and a cancelled job is
    listed (as completing, CG) until its processes are gone. A guard against jobs that never go, not a bound on how
    soon they do."""
    deadline = time.monotonic() + HANG_GUARD_S
    while (jobs := _queued()) and time.monotonic() < deadline:
        time.sleep(0.5)
    return jobs


def _results(out: Path) -> pd.DataFrame:
    frame = pd.read_parquet(out / "results")
    return frame.sort_values(["cell", "pad", "condition", "cv", "model"]).reset_index(drop=True)


def test_a_sweep_through_slurm_equals_the_local_cluster_row_for_row(tmp_path):
    assert shutil.which("sbatch") and _queued() == [], "start SLURM first: scripts/slurm_localhost.sh start"
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    env = {**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache"),
           "DASK_JOBQUEUE__SLURM__CORES": "1", "DASK_JOBQUEUE__SLURM__PROCESSES": "1",
           "DASK_JOBQUEUE__SLURM__MEMORY": "1GiB", "DASK_JOBQUEUE__SLURM__WALLTIME": "00:20:00",
           "DASK_JOBQUEUE__SLURM__NAME": JOB_NAME, "DASK_JOBQUEUE__SLURM__LOG_DIRECTORY": str(tmp_path / "logs")}
    slurm = _explore(sweep, tmp_path / "slurm", env, "--scheduler", "slurm", "--jobs", "2")
    assert slurm.returncode == 0, slurm.stderr
    assert "2 cells computed" in slurm.stdout
    assert sorted(p.suffix for p in (tmp_path / "logs").iterdir()) == [".err", ".err", ".out", ".out"]  # 2 jobs ran
    assert _left_queued() == []  # cancelled when the sweep ended
    local = _explore(sweep, tmp_path / "local", env, "--jobs", "2")
    assert local.returncode == 0, local.stderr
    pd.testing.assert_frame_equal(_results(tmp_path / "slurm"), _results(tmp_path / "local"), check_exact=True)
    assert (tmp_path / "slurm" / "summary.csv").read_bytes() == (tmp_path / "local" / "summary.csv").read_bytes()


def test_a_job_queue_without_its_settings_is_one_line_and_leaves_no_job(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP)
    env = {key: value for key, value in os.environ.items() if not key.startswith("DASK_JOBQUEUE__")}
    env.update(ROUGHSENSE_CACHE_DIR=str(tmp_path / "cache"), DASK_CONFIG=str(tmp_path / "no-dask-config"))
    result = _explore(sweep, tmp_path / "out", env, "--scheduler", "slurm")
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert lines[0].startswith("roughsense: error: --scheduler slurm: cannot start the cluster") and "CORES" in lines[0]
    assert _queued() == []


def test_ctrl_c_cancels_the_batch_jobs(tmp_path):
    import signal

    sweep = tmp_path / "sweep.toml"
    sweep.write_text(small_sweep(range(200)))
    env = {**os.environ, "ROUGHSENSE_CACHE_DIR": str(tmp_path / "cache"),
           "DASK_JOBQUEUE__SLURM__CORES": "1", "DASK_JOBQUEUE__SLURM__PROCESSES": "1",
           "DASK_JOBQUEUE__SLURM__MEMORY": "1GiB", "DASK_JOBQUEUE__SLURM__NAME": JOB_NAME,
           "DASK_JOBQUEUE__SLURM__LOG_DIRECTORY": str(tmp_path / "logs")}
    process = subprocess.Popen([sys.executable, "-m", "roughsense.cli", "explore", str(sweep), "--out",
                                str(tmp_path / "out"), "--scheduler", "slurm", "--jobs", "2"], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                               preexec_fn=sigint_as_in_a_terminal)  # .ci/run may be a background job
    try:
        deadline = time.monotonic() + HANG_GUARD_S
        while not any(line.endswith(" R") for line in _queued()):  # a job is running a worker
            assert process.poll() is None, process.stderr.read()
            assert time.monotonic() < deadline, "no batch job ever started running"
            time.sleep(0.2)
        process.send_signal(signal.SIGINT)
        process.wait(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert _left_queued() == []  # the jobs went with the run (its exit code is the CLI's Ctrl-C handling, tested elsewhere)
