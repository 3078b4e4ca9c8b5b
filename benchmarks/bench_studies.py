"""A 2-D grid of wheelset variants (speed x conicity, free response from a 5 mm push) in-process
and on a Dask LocalCluster of 1 and 2 worker processes: the same numbers bit for bit, the
throughput per worker, the speed-up of 2 workers over 1, the per-task overhead and a worker's
first-batch cost.

    python benchmarks/bench_studies.py [--speeds 50:60:0.25] [--conicities 0.15:0.45:0.0125]
        [--tstop 2] [--batch-size N] [--threads 1[,2]] [--workers 1,2]

Run it on a free machine for the speed-up (the load average before and after each run is
printed beside its figures, and a note when the machine was busy at the start). It ends with
a summary table: per run, the simulation wall time (and the part of it the workers spent
loading the compiled kernels before their first batch), variants/s, CPU per variant, the load
average (1 min) before and after, and whether the numbers equal the in-process run's; then
the speed-ups of N workers over 1 and over the in-process run.

Figures (all wall seconds on this machine):

- in-process: ``run_grid`` with 1 (and with ``--threads 1,2``, 2) threads (simulation only: the
  translation, shared by every run, and loading the compiled kernels are timed apart); CPU:
  this process's CPU time over the simulation;
- cluster: ``run_grid`` with a DaskExecutor on LocalCluster(n_workers=N, processes=True): the
  simulation wall time (the worker processes already started: their start-up is timed apart),
  the sum of the batches' own times on the workers, each worker's loading of circuitsim's
  compiled kernels before its first batch (numba's disk cache, warm; in the simulation wall
  time), and its first batch's time per variant against the later batches'; CPU: the worker
  processes' CPU time over their batches;
- overhead per task: ((simulation wall - kernel loading) x workers - the batches' own time)
  / batches; and the round trip of an empty task (200 submitted, wall / 200).
"""

from __future__ import annotations

import argparse
import logging
import os
import time

import numpy as np

from circuitsim.compare.sweep_measure import InProcess
from circuitsim.compare.values import parse_values
from circuitsim.mechanics import load_model
from circuitsim.studies.execution import DaskExecutor
from circuitsim.studies.grid import full_grid
from circuitsim.studies.study import run_grid
from circuitsim.synthesis.options import SynthesisOptions


class _CpuTimed:
    """An executor with the CPU seconds of this process while it ran."""

    def __init__(self, inner) -> None:
        self.inner, self.cpu = inner, 0.0

    def __call__(self, *args):
        started = time.process_time()
        try:
            return self.inner(*args)
        finally:
            self.cpu = time.process_time() - started


def _empty() -> int:
    return 0


def _round_trip(client, count: int = 200) -> float:
    started = time.perf_counter()
    futures = [client.submit(_empty, pure=False) for _ in range(count)]
    client.gather(futures)
    return (time.perf_counter() - started) / count


def _load() -> float:
    """The machine's load average over the last minute."""
    return os.getloadavg()[0]


def _in_process(systems, grid, options, threads: int) -> dict:
    """One in-process run with ``threads`` threads: its summary row (and prints its line)."""
    executor = _CpuTimed(InProcess(threads))
    before = _load()
    result = run_grid(systems, grid, options=options, window=1.0, executor=executor)
    after = _load()
    s = result.sweep
    wall = s.timings["simulation"]
    print(f"in-process, {threads} thread(s): synthesis {s.timings['synthesis']:.2f} s, "
          f"simulation {wall:.2f} s = {len(grid) / wall:.1f} variants/s; CPU "
          f"{1e3 * executor.cpu / len(grid):.1f} ms per variant; shared start "
          f"{s.stats['shared_start']}; load {before:.2f} -> {after:.2f}")  # fmt: skip
    label = f"in-process, {threads} thread{'' if threads == 1 else 's'}"
    return {"label": label, "wall": wall, "loading": 0.0, "cpu": executor.cpu,
            "before": before, "after": after, "result": result, "workers": 0}  # fmt: skip


def _on_cluster(systems, grid, options, workers: int, batch_size, reference) -> dict:
    """One run on a LocalCluster of ``workers`` processes: its row (and prints its line)."""
    import distributed

    before = _load()
    started = time.perf_counter()
    with distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
        silence_logs=logging.ERROR,
    ) as cluster, distributed.Client(cluster) as client:  # fmt: skip
        client.wait_for_workers(workers)
        up = time.perf_counter() - started
        executor = DaskExecutor(client, batch_size=batch_size)
        result = run_grid(systems, grid, options=options, window=1.0, executor=executor)
        trip = _round_trip(client)
    after = _load()
    s, x = result.sweep, executor.stats
    wall = s.timings["simulation"]
    busy = wall - x["warm_up_wall_s"]  # the batches' part of the wall time
    overhead = (busy * workers - x["batch_wall_s"]) / x["batches"]
    warm = ", ".join(f"{w:.2f}" for w in x["warm_up_s"])
    first, later = {}, []
    for info in x["batch_info"]:  # in the order they ended: a worker's first ends first
        per = info["wall_s"] / info["variants"]
        (later.append(per) if info["pid"] in first else first.setdefault(info["pid"], per))
    cpu = sum(i["cpu_s"] for i in x["batch_info"])
    excess = ", ".join(f"{v / np.mean(later):.2f}" for v in first.values()) if later else "-"
    print(f"dask LocalCluster {workers} worker(s): cluster start {up:.2f} s; simulation "
          f"{wall:.2f} s = {len(grid) / wall:.1f} variants/s "
          f"({len(grid) / wall / workers:.1f} per worker); {x['batches']} batches of "
          f"{x['batch_size']}; batches' own time {x['batch_wall_s']:.2f} s, CPU "
          f"{cpu:.2f} s = {1e3 * cpu / len(grid):.1f} ms per variant; kernel loading "
          f"before the first batch {warm} s; first batch's time per variant / later "
          f"batches' {excess}; overhead per task {overhead:.3f} s; empty-task round "
          f"trip {1e3 * trip:.2f} ms; identical to in-process: {_same(result, reference)}; "
          f"load {before:.2f} -> {after:.2f}")  # fmt: skip
    label = f"LocalCluster, {workers} worker{'' if workers == 1 else 's'}"
    return {"label": label, "wall": wall, "loading": x["warm_up_wall_s"], "cpu": cpu,
            "before": before, "after": after, "result": result, "workers": workers}  # fmt: skip


def _same(result, reference) -> str:
    """Whether a run's peaks equal the reference run's, bit for bit (else how they differ)."""
    ours = np.concatenate([result.sweep.peak_late, result.sweep.peak_all])
    theirs = np.concatenate([reference.sweep.peak_late, reference.sweep.peak_all])
    count = len(result.sweep.peak_late)
    differ = np.unique(np.flatnonzero(ours != theirs) % count)
    if differ.size == 0:
        return "yes"
    largest = np.max(np.abs(ours - theirs) / np.abs(theirs))
    return (f"NO: {differ.size} variants differ (first {differ[:8]}), largest relative "
            f"difference {largest:.3g}")  # fmt: skip


def _summary(rows: list[dict], variants: int) -> None:
    """The comparison table and the speed-ups: ratios of the simulation wall times, and of
    the same without the workers' kernel loading before their first batch (batches only)."""
    reference = rows[0]["result"]
    print()
    print(f"{'run':<26} {'wall s':>8} {'of it loading':>14} {'variants/s':>11} "
          f"{'CPU ms/variant':>15} {'load before -> after':>21}  same numbers")  # fmt: skip
    for row in rows:
        same = "(reference)" if row["result"] is reference else _same(row["result"], reference)
        print(f"{row['label']:<26} {row['wall']:>8.2f} {row['loading']:>14.2f} "
              f"{variants / row['wall']:>11.1f} {1e3 * row['cpu'] / variants:>15.2f} "
              f"{row['before']:>11.2f} -> {row['after']:<6.2f}  {same}")  # fmt: skip

    def ratio(slow: dict, fast: dict) -> str:
        batches = (slow["wall"] - slow["loading"]) / (fast["wall"] - fast["loading"])
        return f"{slow['wall'] / fast['wall']:.2f} (batches only {batches:.2f})"

    single = next((r for r in rows if r["workers"] == 1), None)
    for row in rows:
        if row["workers"] > 1 and single is not None:
            print(f"speed-up of {row['workers']} workers over 1 worker: {ratio(single, row)}")
        if row["workers"]:
            print(f"speed-up of {row['label']} over {rows[0]['label']}: "
                  f"{ratio(rows[0], row)}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default="50:60:0.25")  # 41 values
    parser.add_argument("--conicities", default="0.15:0.45:0.0125")  # 25 values
    parser.add_argument("--tstop", type=float, default=2.0)
    parser.add_argument("--batch-size", type=int)
    parser.add_argument("--threads", default="1", help="in-process runs' threads, e.g. 1,2")
    parser.add_argument("--workers", default="1,2")
    args = parser.parse_args()
    axes = [parse_values(args.speeds), parse_values(args.conicities)]
    grid = full_grid(["V", "lambda"], ["m/s", "1"], axes)
    model = load_model()
    started = time.perf_counter()
    systems = [
        model.system("derived", {"a": 0.0, "y0": 0.005, **dict(grid.assignments(k))})
        for k in range(len(grid))
    ]
    cores = os.cpu_count() or 1
    load = os.getloadavg()
    print(f"grid {grid.shape[0]} x {grid.shape[1]} = {len(grid)} variants, tstop {args.tstop} s;"
          f" systems {time.perf_counter() - started:.2f} s; load average {load[0]:.2f}, "
          f"{load[1]:.2f}, {load[2]:.2f} (1, 5, 15 min) on {cores} cores")  # fmt: skip
    if load[0] > 0.5:
        print(f"note: the machine is not free (load {load[0]:.2f}): other processes share its "
              f"{cores} cores, and the speed-up below measures that contention too")  # fmt: skip
    options = SynthesisOptions(t_stop=args.tstop)
    rows = [_in_process(systems, grid, options, int(n)) for n in args.threads.split(",")]
    reference = rows[0]["result"]
    for workers in (int(w) for w in args.workers.split(",")):
        rows.append(_on_cluster(systems, grid, options, workers, args.batch_size, reference))
    _summary(rows, len(grid))


if __name__ == "__main__":
    main()
