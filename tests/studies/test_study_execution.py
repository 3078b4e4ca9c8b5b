"""A grid on a Dask cluster: the in-process run's numbers bit for bit, a failed batch retried,
one that fails every try reported with its variants, the missing extra named; a worker process
that dies in the middle of a batch (os._exit, as a crash or the out-of-memory killer would end
it) loses nothing, and a batch that kills every worker it runs on is reported as such.

On one worker process a death used to stop the study: the base circuit and the measurement
were scattered, the dead worker took the only copy with it and every later batch was cancelled
("already forgotten"), reported as a batch that "failed on <retries + 1> tries".
"""

import csv
import functools
import logging
import os
import subprocess
import sys
import threading
from pathlib import Path

import dask
import numpy as np
import pytest

from circuitsim.mechanics import load_model
from circuitsim.studies import execution
from circuitsim.studies.errors import ClusterError, StudyError
from circuitsim.studies.execution import DaskExecutor, parse_scheduler, run_batch
from circuitsim.studies.grid import full_grid
from circuitsim.studies.study import run_grid
from circuitsim.synthesis.options import SynthesisOptions

distributed = pytest.importorskip(
    "distributed", reason="dask distributed is not installed (pip install circuitsim[cluster])"
)

ROOT = Path(__file__).resolve().parents[2]
T_STOP = 0.4
WINDOW = 0.2


@pytest.fixture(scope="module")
def client():
    """Two in-process workers (threads): no worker start-up, the same code path."""
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def study():
    grid = full_grid(
        ["V", "lambda"], ["m/s", "1"], [np.array([50.0, 56.0, 62.0]), np.array([0.2, 0.35])]
    )
    model = load_model()
    systems = [
        model.system("derived", {"a": 0.0, "y0": 0.005, **dict(grid.assignments(k))})
        for k in range(len(grid))
    ]
    options = SynthesisOptions(t_stop=T_STOP)
    alone = run_grid(systems, grid, options=options, window=WINDOW, workers=1)
    return grid, systems, options, alone


def same(a, b):
    np.testing.assert_array_equal(a.sweep.peak_late, b.sweep.peak_late)
    np.testing.assert_array_equal(a.sweep.peak_all, b.sweep.peak_all)
    assert a.csv_text() == b.csv_text()


def test_a_dask_run_equals_the_in_process_run_bit_for_bit(client, study):
    grid, systems, options, alone = study
    executor = DaskExecutor(client, batch_size=2)
    on_cluster = run_grid(systems, grid, options=options, window=WINDOW, executor=executor)
    same(alone, on_cluster)
    assert executor.stats["batches"] == 3 and executor.stats["workers"] == 2
    assert on_cluster.sweep.stats["shared_start"] == len(grid)


_ATTEMPTS: dict[int, int] = {}
_LOCK = threading.Lock()


def fails_once(circuits, base, measure, first, threads):
    """The batch task, failing on its first try (a worker that died mid-batch)."""
    with _LOCK:
        _ATTEMPTS[first] = _ATTEMPTS.get(first, 0) + 1
        attempt = _ATTEMPTS[first]
    if attempt == 1:
        raise RuntimeError(f"batch {first}: worker lost (test)")
    return run_batch(circuits, base, measure, first, threads)


def always_fails(circuits, base, measure, first, threads):
    if first >= 2:
        raise RuntimeError("disk full (test)")
    return run_batch(circuits, base, measure, first, threads)


def test_a_batch_that_failed_is_retried_and_nothing_is_lost(client, study):
    grid, systems, options, alone = study
    _ATTEMPTS.clear()
    executor = DaskExecutor(client, batch_size=4, retries=1, batch=fails_once)
    on_cluster = run_grid(systems, grid, options=options, window=WINDOW, executor=executor)
    assert _ATTEMPTS == {0: 2, 4: 2}  # each batch failed once, then ran
    same(alone, on_cluster)


def test_a_batch_that_fails_every_try_stops_the_study_naming_its_variants(client, study):
    grid, systems, options, _ = study
    executor = DaskExecutor(client, batch_size=2, retries=1, batch=always_fails)
    with pytest.raises(ClusterError, match=r"variants (2 to 3|4 to 5) \(batch [23] of 3\) "
                       r"failed on 2 tries: RuntimeError: disk full \(test\)"):  # fmt: skip
        run_grid(systems, grid, options=options, window=WINDOW, executor=executor)


def dies_once(circuits, base, measure, first, threads, flag: str):
    """The batch task; batch 0's first try ends its worker process at once, leaving the
    worker's pid in ``flag`` (the file exists from then on: later tries run, and leave their
    pid in ``flag``.rerun)."""
    if first == 0:
        try:
            fd = os.open(flag, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            Path(flag + ".rerun").write_text(str(os.getpid()))
        else:
            os.write(fd, str(os.getpid()).encode())
            os.close(fd)
            os._exit(70)  # no cleanup, no reply to the scheduler: a dead process
    return run_batch(circuits, base, measure, first, threads)


def always_dies(circuits, base, measure, first, threads):
    if first == 0:
        os._exit(70)
    return run_batch(circuits, base, measure, first, threads)


def process_cluster(workers: int):
    """Worker processes under nannies (a dead one is started again), as ``local:N`` makes."""
    return distributed.LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.CRITICAL,  # the scheduler logs the death as an error
    )


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_a_worker_killed_mid_batch_loses_nothing(study, tmp_path, workers):
    grid, systems, options, alone = study
    flag = tmp_path / "killed.pid"
    with process_cluster(workers) as cluster, distributed.Client(cluster) as client:
        batch = functools.partial(dies_once, flag=str(flag))
        executor = DaskExecutor(client, batch_size=2, retries=0, batch=batch)
        on_cluster = run_grid(systems, grid, options=options, window=WINDOW, executor=executor)
    # batch 0 killed its worker, and ran again in another process
    dead, rerun = int(flag.read_text()), int(Path(f"{flag}.rerun").read_text())
    assert rerun != dead and len(executor.stats["batch_info"]) == 3
    same(alone, on_cluster)


@pytest.mark.slow
def test_a_batch_that_kills_every_worker_is_reported_as_such(study):
    grid, systems, options, _ = study
    # no further try after a death: the study stops at the first. The scheduler cannot tell
    # which of the batches queued on the dead worker killed it: each of them counts a death.
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with process_cluster(1) as cluster, distributed.Client(cluster) as client:
            executor = DaskExecutor(client, batch_size=2, retries=2, batch=always_dies)
            with pytest.raises(
                ClusterError,
                match=r"^variants (0 to 1|2 to 3|4 to 5) \(batch [123] of 3\): the worker "
                r"running it died on each of 1 try \(killed, out of memory or crashed; the "
                r"scheduler's distributed.scheduler.allowed-failures is 0\)",
            ):
                run_grid(systems, grid, options=options, window=WINDOW, executor=executor)


def test_scheduler_text_and_the_missing_extra(monkeypatch):
    assert parse_scheduler("local") == ("local", None)
    assert parse_scheduler("local:3") == ("local", 3)
    assert parse_scheduler("tcp://10.0.0.1:8786") == ("tcp://10.0.0.1:8786", None)
    for bad in ("local:0", "local:x", " "):
        with pytest.raises(StudyError):
            parse_scheduler(bad)
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    with pytest.raises(StudyError, match=r"pip install circuitsim\[cluster\]"):
        with execution.dask_client("local:1"):
            pass


@pytest.mark.slow
def test_sweep_verb_on_a_local_process_cluster_writes_the_in_process_csv(tmp_path):
    """Worker processes import circuitsim and load its compiled kernels themselves."""
    grid = tmp_path / "sets.csv"
    grid.write_text("speed (m/s),lambda\n50,0.2\n62,0.35\n56,0.3\n")
    common = ["--coeffs", "derived", "--grid", str(grid), "--amplitude", "0", "--y0", "0.005",
              "--tstop", "0.3", "--window", "0.1"]  # fmt: skip
    outputs = {}
    for label, extra in (("alone", []), ("cluster", ["--scheduler", "local:1"])):
        out = subprocess.run(
            [sys.executable, "-m", "circuitsim", "sweep", *common, *extra,
             "--out", str(tmp_path / label)],
            cwd=ROOT, capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        assert out.returncode == 0, out.stderr
        outputs[label] = (tmp_path / label / "sweep.csv").read_text()
        assert "Traceback" not in out.stderr
    assert "(builtin, dask, 1 worker, ports kernel;" in out.stdout
    assert "cluster: 3 batches of up to 1 variants on 1 workers" in out.stdout
    assert "dask, 1 worker: 3 of 3 variants" in out.stderr  # the progress lines
    assert outputs["alone"] == outputs["cluster"]
    rows = list(csv.DictReader(outputs["alone"].splitlines()))
    assert len(rows) == 6 and {r["variant"] for r in rows} == {"0", "1", "2"}
