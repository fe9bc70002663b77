"""Run a sweep's cells on Dask and keep every finished cell on disk as it arrives.

Cells are independent tasks (``run_cell``); the client writes each result the moment it completes, so a sweep
killed halfway loses at most the cells in flight, and the next run skips everything already written. Workers need
roughsense importable and nothing else: a cell carries its whole definition and returns its rows. Cells are
submitted a window at a time (a few per worker thread), never as one graph: a sweep of many thousand cells starts
computing, and shows progress, as soon as its first cells are in.

A ``--scheduler`` is checked before any client is made: a scheduler file is read here (bounded, JSON with an
``address``), and the address must complete distributed's own connection (an asynchronous ``Client``) within
:data:`PROBE_S`; an HTTP server or a silent socket never does, so it is one line, not a hang. The bound is asyncio's
``wait_for`` around the whole connection: ``Client(timeout=...)`` alone leaves the handshake out of its timeout
(dask/distributed#7698), and against a port that accepts and stays silent it waited past a minute.
``--scheduler slurm`` (``pbs``, ``sge``) starts the workers as batch jobs through dask-jobqueue, configured the Dask
way (``jobqueue.slurm.*`` in ``~/.config/dask/jobqueue.yaml`` or ``DASK_JOBQUEUE__SLURM__...`` variables),
``--jobs`` of them; closing the client cancels them, whether the sweep ended, failed or was interrupted.
"""
from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import shutil
import tempfile
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .._util import interrupt
from .._util.atomic import pid_alive
from .._util.checks import short_repr
from .._util.files import foreign_reason
from .._util.workers import usable_cores
from ..errors import ConfigError, RoughsenseWarning
from .cell import run_cell
from .store import ResultStore
from .sweep import Sweep
from .sweep_cells import Cell

CONNECT_TIMEOUT_S = 5
#: How long a scheduler address has to complete a client's connection: a Dask scheduler does in milliseconds.
PROBE_S = 4.0
#: A scheduler file is a short JSON document (address, id, services, workers): more is not one.
SCHEDULER_FILE_MAX_BYTES = 1_000_000
#: ``--scheduler`` names of the batch systems whose jobs dask-jobqueue runs workers in, and its cluster class for each.
JOB_QUEUES = {"slurm": "SLURMCluster", "pbs": "PBSCluster", "sge": "SGECluster"}
#: Batch jobs at most (``--jobs`` with a job queue): each is a job in someone's queue.
MAX_JOBS = 1000
#: Local worker processes per usable core at most: more only compete for the cores and memory (--jobs).
MAX_WORKERS_PER_CORE = 4
#: Cells in flight at least (and two per worker thread): enough to keep every worker busy, never the whole sweep.
MIN_WINDOW = 16
CLOSE_TIMEOUT_S = 10
#: How often a wait for the next cell looks for a stop request (Ctrl-C, SIGTERM): cells take seconds each.
INTERRUPT_POLL_S = 0.1


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
    return usable_cores()


def max_workers() -> int:
    return MAX_WORKERS_PER_CORE * default_workers()


def job_queue(scheduler: str | None) -> str | None:
    """The batch system ``--scheduler`` names (``slurm``, ``pbs``, ``sge``), or None for an address or none."""
    name = (scheduler or "").strip().lower()
    return name if name in JOB_QUEUES else None


def check_options(n_jobs: int | None, scheduler: str | None) -> None:
    """``--jobs`` and ``--scheduler`` as given, refused before any folder or cluster is made."""
    if job_queue(scheduler):
        if n_jobs is not None and not 1 <= n_jobs <= MAX_JOBS:
            raise ConfigError(f"--jobs (batch jobs with --scheduler {job_queue(scheduler)}) must be from 1 to "
                              f"{MAX_JOBS}, got {short_repr(n_jobs)}")
        return
    if n_jobs is not None and scheduler is not None:
        raise ConfigError("give --jobs or --scheduler, not both (an existing cluster has its own workers)")
    if scheduler is not None and not scheduler.strip():
        scheduler_address(scheduler)  # the one message for an empty address
    check_workers(n_jobs)


def check_workers(n_jobs: int | None) -> None:
    """``--jobs`` (local worker processes) from 1 to :func:`max_workers`."""
    if n_jobs is None:
        return
    limit = max_workers()
    if not 1 <= n_jobs <= limit:
        raise ConfigError(f"--jobs must be from 1 to {limit} ({MAX_WORKERS_PER_CORE} per usable core of this "
                          f"machine; more processes only compete for them), got {short_repr(n_jobs)}")


def scheduler_address(value: str) -> str:
    """The ``tcp://HOST:PORT`` that ``--scheduler`` names (an address, or a scheduler file holding one), checked to
    answer as a Dask scheduler; anything else is one line naming the option (and the file)."""
    text = value.strip()
    if not text:
        raise ConfigError("--scheduler is empty: give an address (tcp://HOST:8786) or a scheduler file (.json), or "
                          "leave the option out for a local cluster")
    if "://" not in text and (text.lower().endswith(".json") or os.sep in text or Path(text).exists()):
        text = _address_in_file(Path(text))
    host, port = _host_port(text, value)
    address = f"tcp://{host}:{port}"
    _probe(address)
    return address


def _address_in_file(path: Path) -> str:
    def refuse(why: str) -> ConfigError:
        return ConfigError(f"--scheduler: {why}", path=path)

    if not path.is_file():
        raise refuse("no such scheduler file" if not path.exists() else "is not a file")
    try:
        if path.stat().st_size > SCHEDULER_FILE_MAX_BYTES:
            raise refuse(f"is not a Dask scheduler file (over {SCHEDULER_FILE_MAX_BYTES // 1000} kB)")
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        raise refuse('is not a Dask scheduler file (expected JSON with an "address")') from None
    address = document.get("address") if isinstance(document, dict) else None
    if not isinstance(address, str) or not address.strip():
        raise refuse('is not a Dask scheduler file (no "address" in it)')
    return address.strip()


def _host_port(text: str, value: str) -> tuple[str, int]:
    """Host and port of ``tcp://HOST:PORT`` or ``HOST:PORT`` (Dask's default protocol)."""
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme.lower() != "tcp":
        raise ConfigError(f"--scheduler {short_repr(value)}: only tcp:// addresses are supported (the Dask "
                          f"scheduler's default), got {short_repr(scheme + '://')}")
    host, colon, port = rest.rstrip("/").rpartition(":")
    if not colon or not host or not port.isascii() or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"--scheduler {short_repr(value)}: neither a scheduler file (.json) nor an address like "
                          "tcp://HOST:8786")
    return host, int(port)


def _probe(address: str) -> None:
    """Refuse, within :data:`PROBE_S`, an address where nothing listens or something other than Dask answers: a
    client connects there through distributed's public API, bounded as a whole, and closes again."""
    import asyncio

    from .cell import error_line

    try:
        asyncio.run(_connect_and_close(address))
    except TimeoutError:
        raise ConfigError(f"--scheduler {short_repr(address)}: cannot reach the Dask scheduler (no Dask "
                          f"scheduler answered within {PROBE_S:g} s)") from None
    except Exception as exc:  # refused, reset, not Dask's protocol: one line whatever distributed raises
        raise ConfigError(f"--scheduler {short_repr(address)}: cannot reach the Dask scheduler "
                          f"({error_line(exc)})") from None


async def _connect_and_close(address: str) -> None:
    import asyncio

    from distributed import Client

    client = Client(address, asynchronous=True, timeout=PROBE_S, set_as_default=False)
    try:
        await asyncio.wait_for(client.__aenter__(), PROBE_S)  # the handshake included, which timeout= leaves out
    finally:
        await client.close()


def connect(n_jobs: int | None = None, scheduler: str | None = None, *, scratch: Path | None = None):
    """A Dask client: on an existing scheduler (address or scheduler file), on workers in batch jobs
    (``slurm``, ``pbs``, ``sge``), or on a new LocalCluster whose workers keep their scratch files in ``scratch``
    (never ``$TMPDIR``)."""
    from distributed import Client, LocalCluster

    if job_queue(scheduler):
        return _job_queue_client(job_queue(scheduler), 1 if n_jobs is None else int(n_jobs))
    if scheduler is not None:
        address = scheduler_address(scheduler)
        try:
            return Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except Exception as exc:  # it answered the probe, then failed the handshake: still one line
            from .cell import error_line

            raise ConfigError(f"--scheduler {short_repr(address)}: cannot reach the Dask scheduler "
                              f"({error_line(exc)})") from None
    check_workers(n_jobs)
    n = default_workers() if n_jobs is None else int(n_jobs)
    with interrupt.children_ignore_sigint():  # Ctrl-C stops this process, which closes the workers quietly
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR, local_directory=None if scratch is None else str(scratch))
    return Client(cluster, set_as_default=False)


def _job_queue_client(kind: str, jobs: int):
    """A client on a dask-jobqueue cluster of ``kind`` scaled to ``jobs`` batch jobs; its settings are Dask's
    configuration (``jobqueue.<kind>``), so a site's jobqueue.yaml applies unchanged."""
    from distributed import Client

    from .cell import error_line

    try:
        import dask_jobqueue
    except ImportError as exc:
        raise ConfigError(f"--scheduler {kind} needs dask-jobqueue ({error_line(exc)})") from None
    try:
        cluster = getattr(dask_jobqueue, JOB_QUEUES[kind])()
    except Exception as exc:  # a missing setting (cores, memory) or a batch system that is not there: one line
        raise ConfigError(f"--scheduler {kind}: cannot start the cluster ({error_line(exc)}); set jobqueue.{kind}.cores "
                          f"and .memory in ~/.config/dask/jobqueue.yaml or DASK_JOBQUEUE__{kind.upper()}__CORES and "
                          f"__MEMORY") from None
    try:
        cluster.scale(jobs=jobs)
        return Client(cluster, set_as_default=False)
    except BaseException:
        cluster.close()
        raise


def _failure(cell: Cell, error: str) -> dict:
    return {"cell": cell.id, "seed": cell.seed, **cell.columns(), "error": error}


def run_sweep(sweep: Sweep, out: str | os.PathLike[str], *, n_jobs: int | None = None,
              scheduler: str | None = None, force: bool = False,
              progress: Callable | None = None, task: Callable = run_cell) -> SweepOutcome:
    """Compute every unfinished cell of ``sweep`` into ``out``; ``progress(iterable, total=, description=)`` may
    wrap the stream of finished cells (the CLI's bar). Failing cells are recorded, never raised. ``task`` computes
    one cell (an importable function; tests replace it). ``n_jobs`` is ``--jobs``: local worker processes, or batch
    jobs with a job queue."""
    started = time.perf_counter()
    check_options(n_jobs, scheduler)
    store = ResultStore(out, sweep, force=force)  # refuses a wrong folder before any cluster starts
    done = store.finished()  # the files already there: another sweep's are never its cells, so prepare() can wait
    todo = [c for c in sweep.cells if c.id not in done]
    scratch = _scratch(Path(out)) if todo and scheduler is None else None
    client = None
    try:
        with _temporary_directory(scratch):
            client = connect(n_jobs, scheduler, scratch=scratch) if todo else None  # nothing to run: no cluster
        dropped = store.prepare()
        outcome = SweepOutcome(Path(out), len(sweep.cells), len(sweep.cells) - len(todo), 0, dropped=dropped)
        if todo:
            _compute(client, store, todo, outcome, progress, task)
        store.write_failures(outcome.failures)
    finally:
        if client is not None:
            _close(client)
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
    outcome.seconds = time.perf_counter() - started
    return outcome


def _temporary_directory(scratch: Path | None):
    """Dask's ``temporary-directory`` set to ``scratch`` while the local cluster starts (its scheduler, nannies and
    workers all place their lock files there), or nothing to change."""
    import contextlib

    import dask

    return contextlib.nullcontext() if scratch is None else dask.config.set({"temporary-directory": str(scratch)})


def _scratch(out: Path) -> Path:
    """A folder under ``out`` for the local workers' spill and lock files, named as roughsense's temporary files
    are (``.dask-scratch.PID.XXXXXXXX.tmp``), removed when the run ends; a killed run's is removed by the next."""
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob(".dask-scratch.*.tmp"):
        pid = old.name.split(".")[2]
        if not (pid.isdigit() and pid_alive(int(pid))) and foreign_reason(old, folder=True) is None:
            shutil.rmtree(old, ignore_errors=True)  # a killed run's (or one from before the PID was in the name)
    return Path(tempfile.mkdtemp(prefix=f".dask-scratch.{os.getpid()}.", suffix=".tmp", dir=out))


def _compute(client, store: ResultStore, todo: list[Cell], outcome: SweepOutcome, progress, task) -> None:
    stream = _stream(client, todo, task)
    if progress is not None:
        stream = progress(stream, total=len(todo), description="cells")
    for cell, future in stream:
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


def _stream(client, todo: list[Cell], task):
    """(cell, future) as each finishes, keeping a window of cells in flight and submitting the next as one ends."""
    from distributed import as_completed

    waiting = iter(todo)
    cells: dict[str, Cell] = {}
    finished = as_completed([], loop=client.loop)
    threads, checked = 1, -math.inf

    def top_up(window: int) -> None:
        while len(cells) < window:
            cell = next(waiting, None)
            if cell is None:
                return
            future = client.submit(task, cell, key=f"roughsense-cell-{cell.id}", pure=False)
            cells[future.key] = cell
            finished.add(future)

    while True:
        if time.monotonic() - checked > 2.0:  # workers may join a remote cluster while it runs
            threads, checked = max(1, sum(client.nthreads().values())), time.monotonic()
        top_up(max(MIN_WINDOW, 2 * threads))
        if not cells:
            return
        while not finished.has_ready():  # waiting for a cell is a safe point: a stop request is seen within a poll
            interrupt.check()
            time.sleep(INTERRUPT_POLL_S)
        future = next(finished)
        yield cells.pop(future.key), future


def _silence_dask() -> None:
    """Run in each local worker process (and in this one) as the cluster shuts down."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)


def _close(client) -> None:
    """Close the client and its local cluster; a cluster that will not close cleanly (the results are written by
    then) is a warning, never a traceback."""
    cluster = getattr(client, "cluster", None)
    if cluster is not None:  # our own workers: what they log while being stopped (a heartbeat to a closing
        with contextlib.suppress(Exception):  # scheduler) is noise, after the results are written or a stop asked
            client.run(_silence_dask, on_error="ignore")
            _silence_dask()
    try:
        client.close(timeout=CLOSE_TIMEOUT_S)
        if cluster is not None:
            cluster.close(timeout=CLOSE_TIMEOUT_S)
    except Exception as exc:
        from .cell import error_line

        warnings.warn(RoughsenseWarning(f"the Dask cluster did not close cleanly ({error_line(exc)})"), stacklevel=2)
