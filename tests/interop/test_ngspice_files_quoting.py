"""Lines of included files are never quoted in messages, on either engine's path (issue 43).

An included file may be anything the netlist names (``.include /etc/passwd``). Plain ngspice
echoes such a line in its error; the runner's message names the file and line instead, and so
does the builtin engine's reader.
"""

from __future__ import annotations

import os
import subprocess

import pytest

from circuitsim.cli import main
from circuitsim.interop.errors import NgspiceError
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.interop.ngspice_deck import DeckLine, flatten_deck
from circuitsim.interop.ngspice_files import hide_included
from circuitsim.netlist.reader import LIBRARY_DIR
from tests.conftest import NGSPICE, requires_ngspice

SECRETS = {
    # an H card with too few fields: ngspice 39 prints "not enough parameters in line" and it
    "h-card": ("hswordfish hunter2 zebra\n", ["hswordfish", "hunter2", "zebra"], 1),
    # a passwd line: "bad syntax of line" and the line (the second line of the file)
    "passwd": (
        "* users\ngames:x:5:60:topsecretgames:/usr/games:/usr/sbin/nologin\n",
        ["topsecretgames", "games:x", "sbin/nologin"],
        2,
    ),
}
NETLIST = "x\nV1 a 0 DC 1\nR1 a 0 1k\n.include {name}\n.tran 1u 10u\n.end\n"


def _set_up(tmp_path, case):
    text, _, _ = SECRETS[case]
    (tmp_path / "secret.txt").write_text(text)
    (tmp_path / "main.cir").write_text(NETLIST.format(name="secret.txt"))
    return tmp_path / "main.cir"


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("case", SECRETS)
def test_plain_ngspice_quotes_the_included_line(case, tmp_path):
    netlist = _set_up(tmp_path, case)
    done = subprocess.run(
        [NGSPICE, "-b", "-n", netlist.name],
        cwd=tmp_path,
        env={**os.environ, "HOME": str(tmp_path)},
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=120,
    )
    output = done.stdout + done.stderr
    assert all(word in output for word in SECRETS[case][1]), "nothing to hide: proves nothing"


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("case", SECRETS)
def test_the_ngspice_runner_names_file_and_line_only(case, tmp_path, monkeypatch, capsys):
    netlist = _set_up(tmp_path, case)
    _, words, line = SECRETS[case]
    with pytest.raises(NgspiceError) as info:
        run_ngspice(netlist)
    assert not [word for word in words if word in str(info.value)]
    assert f"{tmp_path / 'secret.txt'}:{line} here; an included file: not shown" in str(info.value)
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "main.cir", "--engine", "ngspice"]) == 3
    out, err = capsys.readouterr()
    assert not [word for word in words if word in out + err]
    assert f"secret.txt:{line}" in err


@pytest.mark.parametrize("case", SECRETS)
def test_the_builtin_engine_names_file_and_line_only(case, tmp_path, monkeypatch, capsys):
    _set_up(tmp_path, case)
    _, words, line = SECRETS[case]
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "main.cir"]) == 2
    out, err = capsys.readouterr()
    assert not [word for word in words if word in out + err]
    assert f"secret.txt:{line}: " in err


@requires_ngspice
@pytest.mark.ngspice
def test_a_refused_option_in_an_included_file_is_not_quoted(tmp_path):
    (tmp_path / "main.cir").write_text(NETLIST.format(name="opt.inc"))
    (tmp_path / "opt.inc").write_text(".options measoutfile=/tmp/topsecretname\n")
    with pytest.raises(Exception) as info:
        run_ngspice(tmp_path / "main.cir")
    assert "topsecretname" not in str(info.value)
    assert f"{tmp_path / 'opt.inc'}:1: " in str(info.value)


def _line(text, file="top.cir", number=1, included=False):
    return DeckLine(text, file, number, included)


def test_hide_included_keeps_the_top_netlists_words_and_spice_keywords():
    deck = [
        _line("x1 a b myamp"),
        _line(".subckt myamp inp out", "lib.inc", 1, True),
        _line("rsecret inp out 1k", "lib.inc", 2, True),
        _line("+ 12 34", "lib.inc", 3, True),
        _line(".ends", "lib.inc", 4, True),
    ]
    log = "\n".join(
        [
            "unknown subckt: x1 a b myamp",  # the top file's own line: shown
            "Error on line 3: x1.rsecret x1.inp x1.out 1k",  # quotes lib.inc:2
            "   + 12   34",  # the whole of lib.inc:3 (only short words and digits)
            "subckt expansion failed",  # a SPICE keyword of lib.inc, not its content
        ]
    )
    assert hide_included(log, deck).splitlines() == [
        "unknown subckt: x1 a b myamp",
        "(ngspice's output quotes lib.inc:2 here; an included file: not shown)",
        "(ngspice's output quotes lib.inc:3 here; an included file: not shown)",
        "subckt expansion failed",
    ]


def test_hide_included_leaves_the_part_library_and_plain_decks_alone(tmp_path):
    (tmp_path / "main.cir").write_text("x\n.include parts.lib\nV1 a 0 DC 1\n.op\n.end\n")
    deck = flatten_deck((tmp_path / "main.cir").read_text(), "main.cir", tmp_path)
    assert any(line.included and str(LIBRARY_DIR) in line.file for line in deck)
    log = "\n".join(line.text for line in deck)
    assert hide_included(log, deck) == log
    top = [_line("R1 a 0 1k")]
    assert hide_included("Error: R1 a 0 1k", top) == "Error: R1 a 0 1k"


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("engine", ["builtin", "ngspice"])
def test_an_expression_of_an_included_file_is_not_quoted(engine, tmp_path, monkeypatch, capsys):
    (tmp_path / "secret.txt").write_text("R7 a 0 {zzsecretword*2}\n")
    (tmp_path / "main.cir").write_text(NETLIST.format(name="secret.txt"))
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "main.cir", "--engine", engine]) in (2, 3)
    out, err = capsys.readouterr()
    assert "zzsecretword" not in out + err
