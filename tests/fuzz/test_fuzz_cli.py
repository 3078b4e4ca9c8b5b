"""A bounded, seeded run of the command-line fuzzer (gen_cli.py): hostile options through every
verb, in-process, end in an exit code with at most one error line and no traceback, within the
time bound. The long campaign: ``python -m tests.fuzz.campaign --only gen_cli --count 2000``."""

from tests.fuzz import gen_cli
from tests.fuzz.harness import run_cases

SEED, COUNT, BOUND = 21, 60, 60.0  # generous: a loaded machine is not a hang


def test_hostile_command_lines_end_in_an_exit_code_and_one_line():
    summary = run_cases(gen_cli.cases(SEED, COUNT), time_bound=BOUND)
    report = summary.report()
    assert summary.total == COUNT
    assert summary.count("traceback") == 0, report
    assert summary.count("hang") == 0, report
    assert {domain for domain, _ in summary.counts} == {f"cli-{v}" for v in gen_cli.VERBS}


def test_the_base_command_of_every_verb_is_valid():
    """Each verb's unmutated command runs (reproduce's is refused by design: it is long)."""
    import random

    from tests.fuzz.harness import Case, cli_call, run_case

    rng = random.Random(SEED)
    for verb in ("ode", "stability", "generate", "check", "convert", "simulate", "tolerance",
                 "hunting", "frf", "stepped-sine"):  # fmt: skip
        argv = gen_cli.base_command(rng, verb)
        outcome = run_case(Case("cli", verb, "", cli_call(argv, gen_cli.work_folder())), BOUND)
        assert outcome.kind == "clean", (argv, outcome.detail)
