"""Benchmark harness: our MNA solver against ngspice, at equal accuracy, and speed sweeps.

    python benchmarks/run.py [--quick] [--out DIR] [--parts wheelset golden sweep profile scaling
                                                           macromodels kernels peers]

Parts: ``wheelset`` (work-precision of the generated wheelset circuit, ideal and TL074 op-amps,
against the direct ODE solution), ``golden`` (tests/solver/golden netlists: time ratio and max
deviation against ngspice), ``sweep`` (61-variant speed sweep, builtin runs in a process pool
against one ngspice process per variant), ``profile`` (where the time of one builtin wheelset
run goes: the compiled kernel piece by piece, cProfile of the reference loop), ``scaling``
(chains of N = 1..64 masses with a contact on each, and the wheelset: in-process and
whole-process time against ngspice, accuracy against the direct ODE, growth exponents;
``--sizes`` picks the chains), ``startup`` (whole-process ``simulate`` of the wheelset against
``ngspice -b``, where a process's time goes, the floor of numpy/scipy/numba, peak memory with
and without ``--probe``; median of ``--repeat`` processes), ``macromodels`` (the wheelset with
the JFET-input and bipolar Boyle op-amps of netlist/library/macromodels.lib, and the built-in
TL074: time and accuracy against ngspice and the ODE; only when named in --parts), ``kernels``
(the scaling circuits up to 8 masses on the ports and the MNA kernel, CPU time, against
``kernel="auto"``'s choice; only when named in --parts), ``peers`` (gnucap and VACASK, each
where installed, beside ngspice and ours on the committed wheelset netlists and chains of
1, 4, 16, 64 masses (``--sizes``): CPU time interleaved, the load, accuracy against ngspice
and the ODE; only when named in --parts). ``--family lattice``: ``scaling``
and ``kernels`` on lattices of N masses with one-sided stops (circuitsim.mechanics.lattice), a
family the solver was not tuned on, written to scaling_lattice.* / kernels_lattice.*. Prints text
tables and writes <part>.json / <part>.md and machine.json into --out (default
benchmarks/results). Not part of the test suite.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_common  # noqa: E402
import bench_golden  # noqa: E402
import bench_kernels  # noqa: E402
import bench_macromodels  # noqa: E402
import bench_peers  # noqa: E402
import bench_profile  # noqa: E402
import bench_scaling  # noqa: E402
import bench_startup  # noqa: E402
import bench_sweep  # noqa: E402
import bench_wheelset  # noqa: E402

PARTS = {
    "wheelset": bench_wheelset,
    "golden": bench_golden,
    "sweep": bench_sweep,
    "profile": bench_profile,
    "scaling": bench_scaling,
    "startup": bench_startup,
    "macromodels": bench_macromodels,
    "kernels": bench_kernels,
    "peers": bench_peers,
}
BY_NAME = ("macromodels", "kernels", "peers")  # run only when named in --parts


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer settings and variants")
    parser.add_argument("--out", default=str(HERE / "results"), help="folder for JSON/markdown")
    parser.add_argument(
        "--parts",
        nargs="+",
        choices=list(PARTS),
        default=[p for p in PARTS if p not in BY_NAME],
    )
    parser.add_argument("--sweep", action="store_true", help="only the sweep part")
    parser.add_argument(
        "--repeat", type=int, default=1, help="wheelset/golden: best of N runs (default 1)"
    )
    parser.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        help="scaling, peers: the chains' masses (default 1 2 4 ... 64; peers 1 4 16 64)",
    )
    parser.add_argument(
        "--family",
        choices=list(bench_scaling.FAMILIES),
        default="chain",
        help="scaling, kernels: the model family (default chain; lattice: not tuned on)",
    )
    args = parser.parse_args(argv)
    if args.sizes:
        bench_scaling.CHAIN_SIZES = tuple(args.sizes)
        bench_peers.SIZES = tuple(args.sizes)
    bench_scaling.FAMILY = args.family
    parts = ["sweep"] if args.sweep else args.parts
    bench_common.REPEAT[0] = args.repeat
    bench_startup.REPEAT[0] = max(args.repeat, 3)
    out = Path(args.out)
    machine = bench_common.machine()
    machine["bytecode"] = bench_common.compile_bytecode()  # the whole processes load it
    print("machine: " + ", ".join(f"{k} {v}" for k, v in machine.items()))
    bench_common.save(out, "machine", machine, "\n".join(f"- {k}: {v}" for k, v in machine.items()))
    for name in parts:
        module = PARTS[name]
        log(f"== {name}")
        started = time.perf_counter()
        data = module.run(out / f"{name}_files", args.quick, log)
        data["quick"] = args.quick
        data["harness_seconds"] = time.perf_counter() - started
        text = module.report(data)
        print()
        print(text)
        family = args.family if name in ("scaling", "kernels") and args.family != "chain" else ""
        bench_common.save(out, "_".join(filter(None, (name, family))), data, text)
    print(f"\nwrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
