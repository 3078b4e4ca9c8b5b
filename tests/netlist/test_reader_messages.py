"""Reader errors stay short and do not show what included files hold; .param chains are linear.

Found by the issue-21 probe: ``.include /etc/passwd`` printed the file's first line, a 1 MB
line made a 2 MB message, and 8,000 chained ``.param`` lines took 57 s in ``check``.
"""

from collections.abc import Iterator, Mapping

import pytest

from circuitsim.netlist.errors import MAX_LINE, NetlistError
from circuitsim.netlist.expressions import evaluate
from circuitsim.netlist.reader import parse_netlist

SECRET = "hunter2-secret-credential"


@pytest.mark.parametrize(
    "content",
    [
        f"root:x:0:0:{SECRET}:/root:/bin/bash\n",  # one word: an element R with no nodes
        f"{SECRET} a b c\n",
        f".param x={{{SECRET}*}}\n",
        f"V1 a 0 SIN(0 1 {SECRET}\n",
        f".model m D(IS={SECRET}\n",
        f"* ok\n.tran 1u {SECRET}\n",
    ],
)
def test_an_error_in_an_included_file_does_not_show_its_content(tmp_path, content):
    (tmp_path / "secret.txt").write_text(content)
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\nV9 z 0 1\n.include secret.txt\n", base_dir=str(tmp_path))
    assert SECRET not in str(info.value)
    assert info.value.file.endswith("secret.txt")  # file and line are still named
    assert info.value.line == content.count("\n")


@pytest.mark.parametrize(
    "line", [f"R1 a b {{{SECRET}*2}}\n", f".param p={{{SECRET}}}\nR1 a b {{p}}\n"]
)
def test_an_expression_from_an_included_file_is_not_quoted_by_flatten(tmp_path, line):
    """flatten names the included file of an expression it cannot evaluate, as the reader
    names the file of a line it cannot read, and never quotes it."""
    from circuitsim.netlist.flatten import flatten

    (tmp_path / "secret.txt").write_text(line)
    circuit = parse_netlist("t\nV9 z 0 1\n.include secret.txt\n", base_dir=str(tmp_path))
    with pytest.raises(NetlistError) as info:
        flatten(circuit)
    assert SECRET not in str(info.value)
    assert "included file" in str(info.value) and "secret.txt" in str(info.value)


def test_an_expression_of_the_netlist_itself_is_still_quoted_by_flatten():
    from circuitsim.netlist.flatten import flatten

    with pytest.raises(NetlistError, match="nosuchparam"):
        flatten(parse_netlist("t\nV9 z 0 1\nR1 z 0 {nosuchparam*2}\n"))


def test_an_error_in_the_netlist_itself_still_shows_the_line():
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\nR1 a b 1k2\n", source="deck.cir")
    assert "R1 a b 1k2" in str(info.value)


@pytest.mark.parametrize("size", [10_000, 1_000_000])
def test_a_long_line_makes_a_short_message(size):
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\nV1 a 0 1 " + "x" * size + "\n")
    message = str(info.value)
    assert len(message) < 4 * MAX_LINE + 2 * MAX_LINE + 200
    assert f"({size} characters)" in message  # says how long the cut word was


def test_many_words_on_a_long_line_are_cut_too():
    with pytest.raises(NetlistError) as info:
        parse_netlist("t\nR1 a b " + " q" * 500_000 + "\n")
    assert len(str(info.value)) < 2000


class CountingParams(Mapping):
    """A parameter table that counts how often it is walked whole."""

    def __init__(self, values: dict[str, float]):
        self.values = values
        self.walks = 0

    def __getitem__(self, key: str) -> float:
        return self.values[key]

    def __iter__(self) -> Iterator[str]:
        self.walks += 1
        return iter(self.values)

    def __len__(self) -> int:
        return len(self.values)


def test_evaluate_does_not_copy_the_parameter_table():
    # the cause of the quadratic .param chain: every evaluation copied the whole table
    params = CountingParams({f"p{k}": float(k) for k in range(1000)})
    assert evaluate("p999 + p1", params) == 1000.0
    assert params.walks == 0
    # a name written in capitals still finds its parameter (one walk, on the miss)
    assert evaluate("P999", params) == 999.0


def test_a_long_param_chain_reads_and_evaluates():
    n = 8000
    lines = ["chain", ".param p0=1"] + [f".param p{k}={{p{k - 1}+1}}" for k in range(1, n)]
    circuit = parse_netlist("\n".join([*lines, f"V1 a 0 {{p{n - 1}}}", "R1 a 0 1k"]))
    from circuitsim.netlist.flatten import flatten

    assert flatten(circuit).element("V1").dc == float(n)
