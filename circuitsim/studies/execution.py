"""Running a study's variants on a Dask distributed cluster, in batches.

Each Dask task is a batch of variants that one worker runs with the compiled kernel
(:func:`~circuitsim.compare.sweep_measure.measure_batch`, as the in-process run does), and
sends back a few numbers per variant, so that the task overhead (scheduling, sending the
circuits: a few kilobytes each) stays small against the batch's run. Every batch is run against
the same base circuit (a task of its own, fetched once by each worker): a variant's values do
not depend on how the study was split, and equal the in-process run's bit for bit.

A batch that raises is run again up to ``retries`` times. A batch whose worker dies (killed,
out of memory, a crash) is rescheduled by Dask itself, on another worker or on the one its
nanny starts in place of the dead one, up to the scheduler's ``allowed-failures`` times
(``distributed.scheduler.allowed-failures``, default 3; ``retries`` does not count these).
The base circuit and the measurement are tasks, not scattered data, so that the scheduler
can compute them again when the only worker holding them dies. A batch that fails on every
try stops the study with a :class:`ClusterError` naming its variants and why.

``distributed`` is an optional dependency (``pip install circuitsim[cluster]``): imported
here only when a scheduler is asked for.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

from circuitsim.compare.sweep_measure import Advance, VariantMeasure, VariantOutcome, measure_batch
from circuitsim.netlist.circuit import Circuit
from circuitsim.studies.errors import ClusterError, StudyError

INSTALL_HINT = "pip install circuitsim[cluster]"

# the first batch a worker process runs loads the compiled kernels (numba's disk cache)
_WARM: dict[str, float] = {}


def _distributed():
    try:
        import distributed
    except ImportError:
        raise StudyError(
            f"--scheduler needs dask distributed, which is not installed: {INSTALL_HINT}"
        ) from None
    return distributed


def parse_scheduler(text: str) -> tuple[str, int | None]:
    """``"local"`` or ``"local:N"`` -> ("local", N or None); anything else is an address,
    returned as ("address", None) after a check that it looks like one.

    Raises
    ------
    StudyError
        ``local:`` without a positive whole number, or an empty address.
    """
    text = text.strip()
    if text == "local" or text.startswith("local:"):
        count = text.partition(":")[2]
        if not count:
            return "local", None
        if not count.isdigit() or int(count) < 1:
            raise StudyError(f"--scheduler {text}: expected local or local:N with N >= 1 workers")
        return "local", int(count)
    if not text:
        raise StudyError("--scheduler: expected an address (tcp://HOST:8786) or local[:N]")
    return text, None


@contextlib.contextmanager
def dask_client(scheduler: str, threads: int = 1) -> Iterator:
    """A ``distributed.Client`` for ``scheduler``: a scheduler's address, or ``local[:N]``
    (a LocalCluster of N worker processes, default the CPU count, ``threads`` threads each,
    no dashboard), closed (with its cluster) on leaving.

    Raises
    ------
    StudyError
        distributed not installed, or a malformed ``scheduler``.
    ClusterError
        The scheduler could not be reached.
    """
    distributed = _distributed()
    kind, count = parse_scheduler(scheduler)
    with contextlib.ExitStack() as stack:
        if kind == "local":
            workers = count or os.cpu_count() or 1
            cluster = stack.enter_context(
                distributed.LocalCluster(
                    n_workers=workers,
                    threads_per_worker=threads,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            )
            address = cluster
        else:
            address = kind
        try:
            client = stack.enter_context(distributed.Client(address, timeout="20s"))
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"--scheduler {scheduler}: cannot reach it: {exc}") from None
        yield client


def run_batch(
    circuits: Sequence[Circuit],
    base: Circuit,
    measure: VariantMeasure,
    first: int,
    threads: int,
) -> tuple[list[VariantOutcome], dict]:
    """One Dask task: a batch of variants (on a worker), and what it cost.

    Returns
    -------
    outcomes : list of VariantOutcome
    info : dict
        ``pid``, ``wall_s`` (the whole task on the worker), ``cpu_s`` (the worker process's
        CPU seconds meanwhile), ``warm_up_s`` (loading the
        compiled kernels, in a worker's first batch only; else 0).
    """
    started, cpu = time.perf_counter(), time.process_time()
    warm = warm_worker()
    outcomes = measure_batch(circuits, base, measure, first, threads)
    info = {
        "pid": os.getpid(),
        "wall_s": time.perf_counter() - started,
        "cpu_s": time.process_time() - cpu,  # the worker process's, its other threads included
        "warm_up_s": warm,
        "variants": len(circuits),
    }
    return outcomes, info


def warm_worker(base: Circuit | None = None, measure: VariantMeasure | None = None) -> float:
    """Load the compiled kernels in this (worker) process once, and with ``base`` and
    ``measure`` run the base circuit (its result dropped: what a variant's first run loads
    besides, from the shared start to the measurement, is loaded then too). Returns the seconds
    it took, 0 when the kernels were loaded already."""
    if "ports" in _WARM:
        return 0.0
    from circuitsim.solver.compiled import warm_up
    from circuitsim.solver.variants import variants_kernel

    started = time.perf_counter()
    warm_up((variants_kernel(base),) if base is not None else ("ports",))  # the batches' one
    if base is not None and measure is not None:
        measure_batch([base], base, measure)
    _WARM["ports"] = time.perf_counter() - started
    return _WARM["ports"]


def _shared(value):
    """A task whose result is ``value``: data every batch needs, that the scheduler can make
    again (from this task) when the workers holding it are lost."""
    return value


def _batch_error(which: str, exc: Exception, retries: int) -> ClusterError:
    """The error of a batch that failed on every try: its worker died each time (Dask's
    KilledWorker, counted by the scheduler's allowed-failures), or it raised each time
    (counted by ``retries``)."""
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        tries = exc.allowed_failures + 1
        return ClusterError(
            f"{which}: the worker running it died on each of {tries} tr"
            f"{'y' if tries == 1 else 'ies'} (killed, out of memory or crashed; the scheduler's "
            f"distributed.scheduler.allowed-failures is {exc.allowed_failures}); the worker "
            f"logs say why. Last worker: {exc.last_worker.address}"
        )
    return ClusterError(f"{which} failed on {retries + 1} tries: {type(exc).__name__}: {exc}")


Batch = Callable[..., tuple[list[VariantOutcome], dict]]


@dataclass
class DaskExecutor:
    """Runs a study's variants on a Dask cluster, ``batch_size`` variants per task.

    Parameters
    ----------
    client : distributed.Client
    batch_size : int, optional
        Variants per task (default: enough batches for four per worker, at most 64
        variants each: small enough for the progress and for load balance, large enough
        that the per-task overhead stays a few percent).
    retries : int
        Further tries of a batch that raised. A batch whose worker died is rescheduled by the
        scheduler, up to its ``distributed.scheduler.allowed-failures`` times (default 3).
    threads : int
        Variants each task runs at once (threads on its worker).
    batch : callable
        The task (:func:`run_batch`; a test replaces it with one that fails once).

    Attributes
    ----------
    stats : dict
        After a run: ``workers``, ``batches``, ``batch_size``, ``batch_wall_s`` (summed on
        the workers), ``warm_up_s`` (per worker process: loading the compiled kernels before
        its first batch), ``warm_up_wall_s`` (the wall time of that, here), ``batch_info`` (each
        batch's ``pid``, ``wall_s``, ``variants``).
    """

    client: object
    batch_size: int | None = None
    retries: int = 2
    threads: int = 1
    batch: Batch = run_batch
    stats: dict = field(default_factory=dict)

    @property
    def workers(self) -> int:
        """Workers the scheduler knows (now; after a run, then: the client may be closed)."""
        if "workers" in self.stats:
            return self.stats["workers"]
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    @property
    def label(self) -> str:
        """For progress messages."""
        return f"dask, {self.workers} worker{'' if self.workers == 1 else 's'}"

    def sizes(self, total: int) -> int:
        """Variants per batch for ``total`` variants."""
        if self.batch_size:
            return max(1, int(self.batch_size))
        return max(1, min(64, math.ceil(total / (4 * self.workers))))

    def __call__(
        self,
        circuits: Sequence[Circuit],
        base: Circuit,
        measure: VariantMeasure,
        advance: Advance | None = None,
    ) -> list[VariantOutcome]:
        distributed = _distributed()
        self.stats = {}
        total = len(circuits)
        size = self.sizes(total)
        workers = self.workers
        starts = list(range(0, total, size))
        client = self.client
        # each worker loads the kernels and runs the base circuit once before its first batch
        # (reported apart; a worker that joins later loads the kernels in its first batch)
        warming = time.perf_counter()
        loading = client.run(warm_worker, base, measure)
        warming = time.perf_counter() - warming
        # tasks, not scattered data: a worker fetches them once (not once per batch), and the
        # scheduler can compute them again if every worker holding them dies (scattered data
        # would be lost with them, and every batch after it)
        stamp = time.time_ns()
        shared_base = client.submit(_shared, base, pure=False, key=f"circuitsim-base-{stamp}")
        shared_measure = client.submit(
            _shared, measure, pure=False, key=f"circuitsim-measure-{stamp}"
        )
        futures = {
            client.submit(
                self.batch,
                list(circuits[a : a + size]),
                shared_base,
                shared_measure,
                a,
                self.threads,
                retries=self.retries,
                pure=False,
                key=f"circuitsim-batch-{a}-{stamp}",
            ): a
            for a in starts
        }
        outcomes: list = [None] * total
        infos: list[dict] = []
        done = 0
        try:
            for future in distributed.as_completed(futures):
                a = futures[future]
                try:
                    batch, info = future.result()
                except Exception as exc:
                    last = min(a + size, total) - 1
                    which = f"variants {a} to {last} (batch {starts.index(a) + 1} of {len(starts)})"
                    raise _batch_error(which, exc, self.retries) from exc
                outcomes[a : a + len(batch)] = batch
                infos.append(info)
                done += len(batch)
                if advance is not None:
                    advance(done, total)
        finally:
            # nothing left running after an error or Ctrl-C
            client.cancel([*futures, shared_base, shared_measure])
        self.stats = {
            "workers": workers,
            "batches": len(starts),
            "batch_size": size,
            "batch_wall_s": float(sum(i["wall_s"] for i in infos)),
            "warm_up_s": [*loading.values(), *(i["warm_up_s"] for i in infos if i["warm_up_s"])],
            "batch_info": infos,
            "warm_up_wall_s": warming,
        }
        return outcomes
