"""A 2-D grid of wheelset variants (speed x conicity, free response from a 5 mm push) in-process
and on a Dask LocalCluster of 1 and 2 worker processes: the same numbers bit for bit, the
throughput per worker, the per-task overhead and a worker's first-batch cost.

    python benchmarks/bench_studies.py [--speeds 50:60:0.25] [--conicities 0.15:0.45:0.0125]
        [--tstop 2] [--batch-size N]

Figures (all wall seconds on this machine, with its load average printed):

- in-process: ``run_grid`` with 1 and with 2 threads (simulation only: the translation, shared
  by every run, and loading the compiled kernels are timed apart);
- cluster: ``run_grid`` with a DaskExecutor on LocalCluster(n_workers=N, processes=True): the
  simulation wall time (the worker processes already started: their start-up is timed apart),
  the sum of the batches' own times on the workers, each worker's loading of circuitsim's
  compiled kernels before its first batch (numba's disk cache, warm; in the simulation wall
  time), and its first batch's time per variant against the later batches';
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


def main() -> None:
    import distributed

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speeds", default="50:60:0.25")  # 41 values
    parser.add_argument("--conicities", default="0.15:0.45:0.0125")  # 25 values
    parser.add_argument("--tstop", type=float, default=2.0)
    parser.add_argument("--batch-size", type=int)
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
    print(f"grid {grid.shape[0]} x {grid.shape[1]} = {len(grid)} variants, tstop {args.tstop} s;"
          f" systems {time.perf_counter() - started:.2f} s; load {os.getloadavg()}")  # fmt: skip
    options = SynthesisOptions(t_stop=args.tstop)
    results = {}
    for threads in (1, 2):
        executor = _CpuTimed(InProcess(threads))
        result = run_grid(systems, grid, options=options, window=1.0, executor=executor)
        cpu = executor.cpu
        results[f"in-process {threads} thread(s)"] = result
        s = result.sweep
        print(f"in-process, {threads} thread(s): synthesis {s.timings['synthesis']:.2f} s, "
              f"simulation {s.timings['simulation']:.2f} s = "
              f"{len(grid) / s.timings['simulation']:.1f} variants/s; CPU "
              f"{1e3 * cpu / len(grid):.1f} ms per variant; shared start "
              f"{s.stats['shared_start']}; load {os.getloadavg()}")  # fmt: skip
    reference = results["in-process 1 thread(s)"]
    for workers in (int(w) for w in args.workers.split(",")):
        started = time.perf_counter()
        with distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster, distributed.Client(cluster) as client:  # fmt: skip
            client.wait_for_workers(workers)
            up = time.perf_counter() - started
            executor = DaskExecutor(client, batch_size=args.batch_size)
            result = run_grid(systems, grid, options=options, window=1.0, executor=executor)
            trip = _round_trip(client)
        s, x = result.sweep, executor.stats
        wall = s.timings["simulation"]
        busy = wall - x["warm_up_wall_s"]  # the batches' part of the wall time
        overhead = (busy * workers - x["batch_wall_s"]) / x["batches"]
        ours = np.concatenate([s.peak_late, s.peak_all])
        theirs = np.concatenate([reference.sweep.peak_late, reference.sweep.peak_all])
        differ = np.flatnonzero(ours != theirs) % len(grid)
        same = "yes" if differ.size == 0 else (
            f"NO: {np.unique(differ).size} variants differ (first {np.unique(differ)[:8]}), "
            f"largest relative difference {np.max(np.abs(ours - theirs) / np.abs(theirs)):.3g}"
        )  # fmt: skip
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
              f"trip {1e3 * trip:.2f} ms; identical to in-process: {same}; "
              f"load {os.getloadavg()}")  # fmt: skip


if __name__ == "__main__":
    main()
