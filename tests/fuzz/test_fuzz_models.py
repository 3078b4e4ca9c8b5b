"""A bounded, seeded run of the model-file fuzzer (gen_models.py): mutated model files through
load, ode, stability and generate end in a clean result or a named error, never a traceback or
a hang. The long campaign: ``python -m tests.fuzz.campaign --only gen_models --count 2000``."""

from tests.fuzz import gen_models
from tests.fuzz.harness import run_cases

SEED, COUNT, BOUND = 21, 100, 60.0  # generous: a loaded machine is not a hang


def test_mutated_model_files_end_cleanly_or_in_named_errors():
    summary = run_cases(gen_models.cases(SEED, COUNT), time_bound=BOUND)
    report = summary.report()
    assert summary.total == COUNT
    assert summary.count("traceback") == 0, report
    assert summary.count("hang") == 0, report
    # the mutations must reach past the reader: some files load and run in every domain
    for domain in gen_models.DOMAINS:
        assert summary.counts[(domain, "clean")] > 0, report


def test_the_same_seed_gives_the_same_files():
    first = [(c.name, c.text) for c in gen_models.cases(SEED, 20)]
    again = [(c.name, c.text) for c in gen_models.cases(SEED, 20)]
    assert first == again and len({text for _, text in first}) > 10
