"""Bounded netlist fuzz: every mutated netlist ends in a result or a named error, in time.

A seeded slice of the campaign (``python -m tests.fuzz.campaign --only gen_netlists`` runs
the long one): 60 mutated netlists, each read and checked, converted to every dialect and
read back, and simulated by the builtin engine with a step budget (``gen_netlists.py``).
A failure prints the inputs that failed, so it can be replayed.
"""

from tests.fuzz import gen_netlists
from tests.fuzz.harness import run_cases

SEED = 20261202
TEXTS = 60


def test_fuzzed_netlists_end_cleanly_or_with_a_named_error():
    summary = run_cases(gen_netlists.cases(SEED, 3 * TEXTS), time_bound=20.0)
    assert summary.total == 3 * TEXTS
    assert summary.count("traceback") == 0 and summary.count("hang") == 0, summary.report()
    # the slice reaches every stage: some inputs are accepted by each domain
    for domain in gen_netlists.DOMAINS:
        assert summary.counts[(domain, "clean")] > 0, summary.table()
