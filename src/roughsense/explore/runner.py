"""Run a sweep's cells on Dask and keep every finished cell on disk as it arrives.

Cells are independent tasks (``run_cell``); the client writes each result the moment it completes, so a sweep
killed halfway loses at most the cells in flight, and the next run skips everything already written. Workers need
roughsense importable and nothing else: a cell carries its whole definition and returns its rows.
"""
from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConfigError
from .cell import run_cell
from .store import ResultStore
from .sweep import Cell, Sweep

CONNECT_TIMEOUT_S = 5


@dataclass
class SweepOutcome:
    out: Path
    total: int
    skipped: int
    computed: int
    failures: list[dict] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    seconds: float = 0.0


def default_workers() -> int:
    """One single-threaded worker process per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def connect(workers: int | None = None, scheduler: str | None = None):
    """A Dask client: on an existing scheduler (address or scheduler file), or on a new LocalCluster."""
    from distributed import Client, LocalCluster

    if scheduler:
        target = Path(scheduler)
        try:
            if target.suffix == ".json" and target.is_file():
                return Client(scheduler_file=str(target), timeout=CONNECT_TIMEOUT_S, set_as_default=False)
            return Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise ConfigError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({reason})") from None
    n = default_workers() if workers is None else int(workers)
    if n < 1:
        raise ConfigError(f"--workers must be at least 1, got {n}")
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    return Client(cluster, set_as_default=False)


def _failure(cell: Cell, error: str) -> dict:
    return {"cell": cell.id, "seed": cell.seed, **cell.columns(), "error": error}


def run_sweep(sweep: Sweep, out: str | os.PathLike[str], *, workers: int | None = None,
              scheduler: str | None = None, force: bool = False,
              progress: Callable | None = None, task: Callable = run_cell) -> SweepOutcome:
    """Compute every unfinished cell of ``sweep`` into ``out``; ``progress(iterable, total=, description=)`` may
    wrap the stream of finished cells (the CLI's bar). Failing cells are recorded, never raised. ``task`` computes
    one cell (an importable function; tests replace it)."""
    started = time.perf_counter()
    store = ResultStore(out, sweep, force=force)  # refuses a wrong folder before any cluster starts
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    done = store.finished()  # the files already there: another sweep's are never its cells, so prepare() can wait
    todo = [c for c in sweep.cells if c.id not in done]
    client = connect(workers, scheduler) if todo else None  # nothing left to run: no cluster (seconds) for nothing
    try:
        dropped = store.prepare()
        outcome = SweepOutcome(Path(out), len(sweep.cells), len(sweep.cells) - len(todo), 0, dropped=dropped)
        if todo:
            _compute(client, store, todo, outcome, progress, task)
        store.write_failures(outcome.failures)
    finally:
        if client is not None:
            _close(client)
    outcome.seconds = time.perf_counter() - started
    return outcome


def _compute(client, store: ResultStore, todo: list[Cell], outcome: SweepOutcome, progress, task) -> None:
    from distributed import as_completed

    futures = client.map(task, todo, key=[f"roughsense-cell-{c.id}" for c in todo], pure=False)
    cells = {f.key: c for f, c in zip(futures, todo)}
    stream = as_completed(futures, loop=client.loop)
    if progress is not None:
        stream = progress(stream, total=len(futures), description="cells")
    for future in stream:
        cell = cells[future.key]
        try:
            result = future.result()
        except Exception as exc:
            from .cell import error_line

            result = {"cell": cell, "results": None, "error": error_line(exc)}
        future.release()
        if result["error"] is None:
            store.write_cell(result["results"], result["specimens"], cell.id)
            outcome.computed += 1
        else:
            outcome.failures.append(_failure(cell, result["error"]))


def _close(client) -> None:
    cluster = client.cluster if hasattr(client, "cluster") else None
    client.close()
    if cluster is not None:
        cluster.close()
