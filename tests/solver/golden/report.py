"""Print deviation and wall time, ours vs ngspice, for every golden netlist (not a test).

Run from the repository root: ``python tests/solver/golden/report.py [repeats]``. Deviation is
max |ours - ngspice| / range of the ngspice signal, over ngspice's time points, worst signal
(node voltages only for switch.cir, as in test_golden.py). Times are the best of ``repeats``:
ours in-process (flatten + assemble + solve), ngspice as a whole ``ngspice -b`` process.
"""

import sys
import time
from pathlib import Path

import numpy as np

from circuitsim.interop.ngspice import run_ngspice
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import simulate

GOLDEN = Path(__file__).parent


def main(repeats: int = 3) -> None:
    print(
        f"{'netlist':26s} {'deviation':>10s} {'signal':>18s} {'ours s':>8s} {'ngspice s':>9s} "
        f"{'steps ours/ng':>14s}"
    )
    for path in sorted(GOLDEN.glob("*.cir")):
        circuit = read_netlist(path)
        ours_t, ng_t = [], []
        for _ in range(repeats):
            start = time.perf_counter()
            ours = simulate(circuit)
            ours_t.append(time.perf_counter() - start)
            ng = run_ngspice(path)
            ng_t.append(ng.stats["wall_time_s"])
        devs = {}
        for name in ng.names:
            if name not in ours.signals or (path.name == "switch.cir" and name[0] != "v"):
                continue
            ref = ng[name]
            err = np.max(np.abs(np.interp(ng.time, ours.time, ours[name]) - ref))
            devs[name] = err / max(float(np.ptp(ref)), 1e-12)
        worst = max(devs, key=devs.get)
        steps = f"{len(ours.time) - 1}/{len(ng.time) - 1}"
        print(
            f"{path.name:26s} {devs[worst]:10.2e} {worst:>18s} {min(ours_t):8.3f} "
            f"{min(ng_t):9.3f} {steps:>14s}"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
