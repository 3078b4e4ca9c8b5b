"""Netlists cannot make ngspice run commands (issue 21, item 1).

Each variant below hides ``shell touch <marker>`` somewhere ngspice 39 executes it. The first
test runs plain ``ngspice -b`` on it the way the runner used to (in the netlist's folder, with
the user's environment): the marker appears, so the variant is a real attack and the checks
after it can fail. Then ``run_ngspice`` and ``circuitsim simulate --engine ngspice`` run the
same files, and the marker must not appear. Where the variant leaves a sound circuit the
result is checked too (v(b) = 0.5 V of the 1 k / 1 k divider), so the sandbox does not buy its
safety by dropping circuit lines.
"""

from __future__ import annotations

import os
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.interop.errors import NgspiceError
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.interop.ngspice_deck import check_inert
from circuitsim.netlist.errors import NetlistError
from tests.conftest import NGSPICE, requires_ngspice

BODY = "V1 a 0 DC 1\nR1 a b 1k\nR2 b 0 1k\n.op\n"
CMD = "shell touch {marker}"


@dataclass(frozen=True)
class Variant:
    """Files (relative to a fresh folder) and environment of one way of smuggling a command.

    ``sound``: the netlist is still the divider once the smuggled part is gone (else ngspice
    reports an error on what is left, which is fine as long as nothing runs).
    """

    name: str
    files: dict[str, str]
    env: dict[str, str] = field(default_factory=dict)  # values relative to the folder
    sound: bool = True


def _with_block(block: str, after_end: str = "") -> str:
    return "divider\n" + BODY + block + ".end\n" + after_end


def _start_up_file(name: str, path: str, **env: str) -> Variant:
    """A sound netlist, and a start-up file of ngspice's (``env``: folders, relative)."""
    return Variant(name, {"main.cir": _with_block(""), path: CMD}, env)


VARIANTS = [
    Variant("control block", {"main.cir": _with_block(f".control\n{CMD}\n.endc\n")}),
    Variant(
        "control block in an included file",
        {"main.cir": _with_block(".include evil.inc\n"), "evil.inc": f".control\n{CMD}\n.endc\n"},
    ),
    Variant(
        "nested include in a subfolder",
        {
            "main.cir": _with_block(".inc 'sub/a.inc'\n"),
            "sub/a.inc": "* relative to sub/\n.include b.inc\n",
            "sub/b.inc": f".control\n{CMD}\n.endc\n",
        },
    ),
    Variant(
        "control block in a .lib section",
        {
            "main.cir": _with_block(".lib evil.lib sect\n"),
            "evil.lib": f"* a library\n.lib sect\n.control\n{CMD}\n.endc\n.endl\n",
        },
    ),
    Variant(
        "control block opened in an include, closed in the netlist",
        {"main.cir": _with_block(f".include open.inc\n{CMD}\n.endc\n"), "open.inc": ".control\n"},
    ),
    Variant("semicolon comments", {"main.cir": _with_block(f".control;x\n{CMD}\n.endc;x\n")}),
    Variant("longer keywords", {"main.cir": _with_block(f".controls\n{CMD}\n.endcs\n")}),
    Variant("upper case", {"main.cir": _with_block(f".CONTROL\n{CMD}\n.ENDC\n")}),
    Variant("mixed case", {"main.cir": _with_block(f".CoNtRoL\n{CMD}\n.EnDc\n")}),
    Variant("leading blanks", {"main.cir": _with_block(f"  \t.control\n {CMD}\n\t .endc\n")}),
    Variant(
        "command continued with +",
        {"main.cir": _with_block(".control\nshell\n+ touch {marker}\n.endc\n")},
    ),
    Variant("block after .end", {"main.cir": _with_block("", f".control\n{CMD}\n.endc\n")}),
    Variant(
        "carriage return inside the keyword",
        {"main.cir": _with_block(f".con\rtrol\n{CMD}\n.en\rdc\n")},
    ),
    Variant("NUL after the keyword", {"main.cir": _with_block(f".control\0junk\n{CMD}\n.endc\n")}),
    Variant("pre_ command", {"main.cir": _with_block(f".control\npre_{CMD}\n.endc\n")}),
    Variant("*# comment line", {"main.cir": _with_block(f"*# {CMD}\n")}),
    Variant("*ng_script first line", {"main.cir": f"*ng_script\n{CMD}\n"}, sound=False),
    Variant(
        ".title *ng_script",
        {"main.cir": "divider\n.title *ng_script\n" + CMD + "\n" + BODY + ".end\n"},
        sound=False,
    ),
    Variant(
        "title line past 4999 bytes",  # ngspice reads the first line in 4999-byte pieces
        {"main.cir": "x" * 4999 + f".control\n{CMD}\n.endc\n" + BODY + ".end\n"},
        sound=False,
    ),
    _start_up_file(".spiceinit beside the netlist", ".spiceinit"),
    _start_up_file("spice.rc beside the netlist", "spice.rc"),
    _start_up_file(".spiceinit in $HOME", "home/.spiceinit", HOME="home"),
    _start_up_file("$SPICE_USERINIT_DIR", "init/.spiceinit", SPICE_USERINIT_DIR="init"),
    _start_up_file("$SPICE_SCRIPTS (another spinit)", "scripts/spinit", SPICE_SCRIPTS="scripts"),
    _start_up_file("$SPICE_LIB_DIR (another spinit)", "lib/scripts/spinit", SPICE_LIB_DIR="lib"),
]


def _set_up(variant: Variant, folder: Path) -> tuple[Path, Path, dict[str, str]]:
    """Write the variant's files; return the netlist, the marker and its environment."""
    marker = folder / "pwned"
    for name, text in variant.files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(text.replace("{marker}", str(marker)).encode())
    (folder / "emptyhome").mkdir()
    env = {"HOME": str(folder / "emptyhome")}  # never the real ~/.spiceinit
    env.update({key: str(folder / value) for key, value in variant.env.items()})
    return folder / "main.cir", marker, env


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("variant", VARIANTS, ids=[v.name for v in VARIANTS])
def test_plain_ngspice_runs_the_command(variant, tmp_path):
    netlist, marker, env = _set_up(variant, tmp_path)
    subprocess.run(
        [NGSPICE, "-b", netlist.name],
        cwd=tmp_path,
        env={**os.environ, **env},
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=120,
    )
    assert marker.exists(), "the variant is no attack on ngspice 39: the tests below prove nothing"


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("variant", VARIANTS, ids=[v.name for v in VARIANTS])
def test_run_ngspice_does_not(variant, tmp_path, monkeypatch):
    netlist, marker, env = _set_up(variant, tmp_path)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    monkeypatch.chdir(tmp_path)
    if variant.sound:
        waves = run_ngspice(netlist)
        assert waves["v(b)"][0] == pytest.approx(0.5, rel=1e-9)
    else:
        with pytest.raises((NgspiceError, NetlistError)):
            run_ngspice(netlist)
    assert not marker.exists()


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("variant", VARIANTS, ids=[v.name for v in VARIANTS])
def test_cli_simulate_does_not(variant, tmp_path, monkeypatch, capsys):
    netlist, marker, env = _set_up(variant, tmp_path)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    monkeypatch.chdir(tmp_path)
    code = main(["simulate", str(netlist), "--engine", "ngspice"])
    out = capsys.readouterr().out
    assert (code == 0) == variant.sound
    if variant.sound:
        assert "v(b) = 0.5  (at t = 0 s)" in out
    assert not marker.exists()


# --- the deck keeps what ngspice reads ----------------------------------------------------

# (netlist files, v(b) in volts for V1 = 1 V through R1 = 1k into what the files put at b)
READING_RULES = {
    "\\\\ continues a line": ({"main.cir": "t\nV1 a 0 DC 1\nR1 a b 1k\nR2 b 0 \\\\\n1k\n"}, 0.5),
    "+ after .title continues the card before": (
        {"main.cir": "t\nV1 a 0 DC 1\nR1 a b 1k\nR2 b 0\n.title other\n+ 1k\n"},
        0.5,
    ),
    "+ after .endc belongs to the dropped block": (
        {"main.cir": "t\nV1 a 0 DC 1\nR1 a b 1k\nR2 b 0 1k\n.control\n.endc\n+ 3k\n"},
        0.5,
    ),
    "@ ends an included file": (
        {
            "main.cir": "t\nV1 a 0 DC 1\nR1 a b 1k\n.inc r.inc\n",
            "r.inc": "R2 b 0 1k\n@\nR3 b 0 1\n",
        },
        0.5,
    ),
    ".end inside an included file is passed over": (
        {
            "main.cir": "t\nV1 a 0 DC 1\nR1 a b 1k\n.inc r.inc\n",
            "r.inc": "R2 b 0 1k\n.end\nR3 b 0 1k\n",
        },
        1 / 3,
    ),
    ".lib takes only its section": (
        {
            "main.cir": "t\nV1 a 0 DC 1\nR1 a b 1k\n.lib 'r.lib' two\n",
            "r.lib": ".lib one\nR2 b 0 1\n.endl\n.lib two\nR2 b 0 3k\n.endl\n",
        },
        0.75,
    ),
    "carriage returns are removed": (
        {"main.cir": "t\r\nV1 a 0 DC 1\r\nR1 a b 1k\r\nR2 b 0 1\rk\n"},
        0.5,
    ),
}


def _plain_ngspice_vb(folder: Path, deck: bytes) -> float:
    """v(b) as ``ngspice -b -n`` prints it for ``deck`` (which holds its own print command)."""
    (folder / "plain.cir").write_bytes(deck)
    done = subprocess.run(
        [NGSPICE, "-b", "-n", "plain.cir"],
        cwd=folder,
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
        timeout=120,
    )
    printed = [line for line in done.stdout.splitlines() if line.startswith("v(b) = ")]
    return float(printed[0].split("=")[1])


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("rule", list(READING_RULES))
def test_the_deck_is_the_circuit_plain_ngspice_reads(rule, tmp_path):
    files, expected = READING_RULES[rule]
    for name, text in files.items():
        (tmp_path / name).write_bytes(text.encode())
    main_text = (tmp_path / "main.cir").read_bytes()
    plain = main_text + b".control\nop\nprint v(b)\n.endc\n.end\n"
    assert _plain_ngspice_vb(tmp_path, plain) == pytest.approx(expected, rel=1e-6)
    (tmp_path / "main.cir").write_bytes(main_text + b".op\n.end\n")
    assert run_ngspice(tmp_path / "main.cir")["v(b)"][0] == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize(
    ("files", "message"),
    [
        ({"main.cir": "t\n.include /dev/zero\n"}, "is not a regular file"),
        ({"main.cir": "t\n.include .\n"}, "is not a regular file"),
        ({"main.cir": "t\n.include nosuch.inc\n"}, "include file 'nosuch.inc' not found"),
        ({"main.cir": "t\n.include a.inc\n", "a.inc": ".include main.cir\n"}, "include cycle"),
        ({"main.cir": "t\n.lib r.lib x\n", "r.lib": ".lib y\n.endl\n"}, "section 'x' not found"),
        ({"main.cir": "t\n.lib r.lib x\n", "r.lib": ".lib x\nR1 a 0 1\n"}, "has no .endl"),
        ({"main.cir": "t\n.include\n"}, ".include needs a file name"),
    ],
)
def test_include_problems_name_the_file_and_line(files, message, tmp_path):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with pytest.raises(NetlistError, match=message) as info:
        run_ngspice(tmp_path / "main.cir")
    assert info.value.line is not None and info.value.file is not None


CARDS_NGSPICE_DOES_NOT_RUN = [
    ".options temp=`touch {marker}`",
    ".options `touch {marker}`",
    ".print op v(`touch {marker}`)",
    ".save v(b) `touch {marker}`",
    ".param p=`touch {marker}`",
    ".width out=`touch {marker}`",
    ".print op v(b) > {marker}",
]


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("card", CARDS_NGSPICE_DOES_NOT_RUN)
def test_backquotes_and_redirections_in_cards_stay_inert(card, tmp_path):
    """Circuit cards are not run through ngspice's command shell (checked, in ngspice 39)."""
    marker = tmp_path / "pwned"
    deck = "t\n" + BODY + card.replace("{marker}", str(marker)) + "\n.end\n"
    (tmp_path / "main.cir").write_text(deck)
    subprocess.run(
        [NGSPICE, "-b", "main.cir"],
        cwd=tmp_path,
        capture_output=True,
        stdin=subprocess.DEVNULL,
        timeout=120,
    )
    assert not marker.exists()
    try:
        run_ngspice(tmp_path / "main.cir")
    except NgspiceError:
        pass  # some of these cards are errors to ngspice: fine, nothing ran
    assert not marker.exists()


@requires_ngspice
@pytest.mark.ngspice
def test_lines_after_end_reach_plain_ngspice_but_not_the_deck(tmp_path):
    """ngspice 39 reads on after ``.end``; the deck stops there, as the netlist reader does."""
    text = "t\nV1 a 0 DC 1\nR1 a b 1k\nR2 b 0 1k\n.op\n.end\nR3 b 0 1\n"
    (tmp_path / "main.cir").write_text(text)
    plain = (text + ".control\nrun\nprint v(b)\n.endc\n").encode()
    shunt = 1e3 * 1.0 / (1e3 + 1.0)  # R2 || R3
    assert _plain_ngspice_vb(tmp_path, plain) == pytest.approx(shunt / (1e3 + shunt), rel=1e-6)
    assert run_ngspice(tmp_path / "main.cir")["v(b)"][0] == pytest.approx(0.5, rel=1e-9)


def test_an_included_files_line_is_not_quoted(tmp_path):
    (tmp_path / "main.cir").write_text("t\n.include secret.txt\n")
    (tmp_path / "secret.txt").write_text("password hunter2\n.include nosuch-hunter2.inc\n")
    with pytest.raises(NetlistError) as info:
        run_ngspice(tmp_path / "main.cir")
    assert "hunter2" not in str(info.value)
    assert f"{tmp_path / 'secret.txt'}:2" in str(info.value)


@requires_ngspice
@pytest.mark.ngspice
def test_ngspice_log_lines_are_cut(tmp_path):
    word = "x" * 1_000_000
    (tmp_path / "main.cir").write_text(
        f"t\nV1 a 0 DC 1\nR1 a 0 1k\nQ{word} a 0 0 nomodel\n.op\n.end\n"
    )
    with pytest.raises(NgspiceError) as info:
        run_ngspice(tmp_path / "main.cir")
    assert len(str(info.value)) < 20_000


@pytest.mark.parametrize(
    "line",
    [
        ".control",
        "  .CONTROL",
        "\t.endc x",
        ".con\rtrol",
        "*# shell x",
        "* a comment",
        ".incl x",
        ".lib 'a.lib' sect",
        ".title x",
        "@",
        "R1 a b 1k\n.control",
    ],
)
def test_check_inert_refuses_what_ngspice_acts_on(line):
    with pytest.raises(RuntimeError, match="still holds a line ngspice acts on"):
        check_inert(["R1 a 0 1k", line])


def test_check_inert_passes_circuit_lines():
    check_inert(["R1 a 0 1k", "+ tc1=0", ".lib sect", ".model d1 d", "$ note", "#x", ".endl"])
