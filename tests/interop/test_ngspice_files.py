"""Netlists cannot make ngspice write (or read) a file outside its private folder (issue 43).

Each write variant sets ngspice's ``measoutfile`` (where ``.meas`` results go) to a victim file
outside the netlist's folder, in one of the ways ngspice 39 takes it. The first test runs plain
``ngspice -b`` on it in the netlist's folder and sees the victim replaced, so each variant is a
live attack and the checks after it can fail. Then ``circuitsim simulate --engine ngspice``
(and, for four variants, ``compare --netlist ... --engine ngspice``) must refuse the netlist
with an error naming the file and line, and the whole temporary tree (netlist folder, victim
folder, the folder ngspice's private folders are made in) must be unchanged afterwards.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.interop.ngspice import _with_control, run_ngspice
from circuitsim.interop.sandbox import bare_environment, confined, run_with_limit
from circuitsim.netlist.errors import NetlistError
from tests.conftest import NGSPICE, requires_ngspice

BODY = "V1 a 0 DC 1\nR1 a 0 1k\n.meas tran vmax max v(a)\n.tran 1u 10u\n"
PRECIOUS = "precious\n"


@dataclass(frozen=True)
class Variant:
    """Files (relative to the netlist's folder, ``{victim}`` for the victim's path) of one way
    of naming ngspice's ``measoutfile``; ``at`` is the file and line the error must name."""

    name: str
    files: dict[str, str]
    at: tuple[str, int]


def _main(cards: str, at: int) -> Variant:
    return Variant("", {"main.cir": "x\n" + BODY + cards + ".end\n"}, ("main.cir", at))


def _named(name: str, variant: Variant) -> Variant:
    return Variant(name, variant.files, variant.at)


WRITES = [
    _named("inline", _main(".options measoutfile={victim}\n", 6)),
    _named("mixed case", _main(".Option MeasOutFile={victim}\n", 6)),
    _named("name in quotes", _main('.options "measoutfile"={victim}\n', 6)),
    _named("blanks around =", _main(".options measoutfile = {victim}\n", 6)),
    _named("backslash in the name", _main(".options measout\\file={victim}\n", 6)),
    _named("+ continuation", _main(".option reltol=1e-3\n+ measoutfile={victim}\n", 7)),
    _named("+ after a vertical tab", _main(".option reltol=1e-3\n\v+ measoutfile={victim}\n", 7)),
    _named("\\\\ continuation", _main(".option reltol=1e-3 \\\\\nmeasoutfile={victim}\n", 7)),
    Variant(
        "included file",
        {
            "main.cir": "x\n" + BODY + ".include opt.inc\n.end\n",
            "opt.inc": ".options measoutfile={victim}\n",
        },
        ("opt.inc", 1),
    ),
    Variant(
        ".lib section",
        {
            "main.cir": "x\n" + BODY + ".lib opts.lib fast\n.end\n",
            "opts.lib": ".lib fast\n.options measoutfile={victim}\n.endl\n",
        },
        ("opts.lib", 2),
    ),
    Variant(
        "+ line in an include continuing the netlist's .options",
        {
            "main.cir": "x\n" + BODY + ".options reltol=1e-3\n.include cont.inc\n.end\n",
            "cont.inc": "+ measoutfile={victim}\n",
        },
        ("cont.inc", 1),
    ),
    Variant(
        "nested include in a subfolder",
        {
            "main.cir": "x\n" + BODY + ".inc sub/a.inc\n.end\n",
            "sub/a.inc": "* relative to sub/\n.include b.inc\n",
            "sub/b.inc": ".OPTIONS MEASOUTFILE={victim}\n",
        },
        ("sub/b.inc", 1),
    ),
]
COMPARED = ["inline", "included file", ".lib section", "+ continuation"]


def _set_up(variant: Variant, root: Path) -> tuple[Path, Path]:
    """The variant's files under ``root/work``, the victim ``root/outside/victim.txt``."""
    victim = root / "outside" / "victim.txt"
    victim.parent.mkdir(parents=True)
    victim.write_text(PRECIOUS)
    assert str(victim) == str(victim).lower(), "ngspice lower-cases an unquoted path"
    for name, text in variant.files.items():
        path = root / "work" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(text.replace("{victim}", str(victim)).encode())
    return root / "work" / "main.cir", victim


def _snapshot(root: Path) -> dict[str, str]:
    """Every file and folder under ``root`` with a hash of its content."""
    tree = {}
    for path in sorted(root.rglob("*")):
        key = str(path.relative_to(root))
        tree[key] = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "dir"
    return tree


@pytest.fixture
def private_parent(tmp_path, monkeypatch):
    """The folder ngspice's private folders are made in (``TMPDIR``), inside ``tmp_path``."""
    parent = tmp_path / "tmp"
    parent.mkdir()
    monkeypatch.setenv("TMPDIR", str(parent))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(parent))
    return parent


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("variant", WRITES, ids=[v.name for v in WRITES])
def test_plain_ngspice_writes_the_victim(variant, tmp_path):
    netlist, victim = _set_up(variant, tmp_path)
    subprocess.run(
        [NGSPICE, "-b", "-n", netlist.name],
        cwd=netlist.parent,
        env={**os.environ, "HOME": str(tmp_path)},
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=120,
    )
    assert "Measurements for Transient Analysis" in victim.read_text(), (
        "the variant is no attack on ngspice 39: the tests below prove nothing"
    )


def _refused(code: int, err: str, variant: Variant, root: Path) -> None:
    file, line = variant.at
    assert code == 2
    assert f"{root / 'work' / file}:{line}: " in err or f"{file}:{line}: " in err
    assert "measoutfile" in err and "private folder" in err
    if file != "main.cir":  # a line of an included file: named, never shown
        assert str(root / "outside") not in err


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("variant", WRITES, ids=[v.name for v in WRITES])
def test_simulate_refuses_it(variant, tmp_path, private_parent, monkeypatch, capsys):
    netlist, victim = _set_up(variant, tmp_path)
    monkeypatch.chdir(netlist.parent)
    before = _snapshot(tmp_path)
    code = main(["simulate", "main.cir", "--engine", "ngspice"])
    err = capsys.readouterr().err
    _refused(code, err, variant, tmp_path)
    assert victim.read_text() == PRECIOUS
    assert _snapshot(tmp_path) == before


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.slow
@pytest.mark.parametrize("name", COMPARED)
def test_compare_refuses_it(name, tmp_path, private_parent, monkeypatch, capsys):
    variant = next(v for v in WRITES if v.name == name)
    netlist, victim = _set_up(variant, tmp_path)
    monkeypatch.chdir(netlist.parent)
    assert main(["generate", "-o", "wheelset.cir"]) == 0
    text = (netlist.parent / "wheelset.cir").read_text()
    cut = text.lower().rindex(".end")
    attack = netlist.read_text().split(".tran 1u 10u\n", 1)[1].rsplit(".end", 1)[0]
    line = text[:cut].count("\n") + 1 + variant.at[1] - 6  # where the attack lands
    netlist.write_text(text[:cut] + ".meas tran vmax max v(y_neg)\n" + attack + text[cut:])
    (netlist.parent / "main.scale.json").write_text(
        (netlist.parent / "wheelset.scale.json").read_text()
    )
    capsys.readouterr()
    before = _snapshot(tmp_path)
    code = main(["compare", "--netlist", "main.cir", "--engine", "ngspice"])
    err = capsys.readouterr().err
    at = variant.at if variant.at[0] != "main.cir" else ("main.cir", line + 1)
    _refused(code, err, Variant(name, variant.files, at), tmp_path)
    assert victim.read_text() == PRECIOUS
    assert _snapshot(tmp_path) == before


@requires_ngspice
@pytest.mark.ngspice
def test_the_runners_block_keeps_meas_output_in_its_folder(tmp_path):
    """The second line of defence: should a measoutfile reach ngspice, the block's own
    ``set measoutfile`` (a global variable, which outranks the circuit's) wins."""
    victim = tmp_path / "victim.txt"
    victim.write_text(PRECIOUS)
    lines = [*BODY.splitlines(), f".options measoutfile={victim}"]
    folder = tmp_path / "private"
    folder.mkdir()
    (folder / "deck.cir").write_text(_with_control(lines, "tran"))
    subprocess.run(
        [NGSPICE, "-b", "-n", "deck.cir"],
        cwd=folder,
        env={"PATH": os.environ["PATH"], "HOME": str(folder)},
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=120,
    )
    assert victim.read_text() == PRECIOUS
    assert "vmax" in (folder / "meas.txt").read_text()
    assert (folder / "out.raw").stat().st_size > 0


REFUSED = [
    (".opt measoutfile=/tmp/x.txt", "measoutfile"),
    (".opts measoutfile=/tmp/x.txt", "measoutfile"),
    (".optfoo measoutfile=/tmp/x.txt", "measoutfile"),
    (".options rawfile=/tmp/x.raw", "rawfile"),
    (".options sourcepath=( /tmp /etc )", "sourcepath"),
    (".options inputdir=/etc", "inputdir"),
    (".options editor=/bin/sh", "editor"),
    (".options spicepath=/bin/sh", "spicepath"),
    (".options remote\x01shell=/bin/sh", "remote_shell"),
    (".options rprogram=/bin/sh rhost=evil.example", "rhost"),
    (".options lprps=lpr", "lprps"),
    (".options helppath=/etc", "helppath"),
    ('.model src filesource (file="/etc/passwd")', "filesource"),
    (".cmodel src filesource (file=/etc/passwd)", "filesource"),
    (".model d1 d_source (input_file=/etc/passwd)", "d_source"),
    (".model st d_state (state_file=/etc/passwd)", "d_state"),
    (".model t2 table2d (file=/etc/passwd)", "table2d"),
    (".MODEL t3 TABLE3D (file=/etc/passwd)", "table3d"),
    (".model n1 numd level=1\n+ output rootfile=/tmp/dump", "rootfile"),
    (".model n1 numd level=1\n+ doping gauss infile=/etc/passwd", "infile"),
    ("d1 a 0 n1 ic.file=/etc/passwd", "ic.file"),
]


@pytest.mark.parametrize("card, word", REFUSED, ids=[w + ": " + c[:20] for c, w in REFUSED])
def test_other_file_names_are_refused(card, word, tmp_path):
    """Cards and options ngspice 39's sources open a file (or run a program) by, refused
    before ngspice starts, naming the file and line."""
    (tmp_path / "main.cir").write_text("x\nV1 a 0 DC 1\nR1 a 0 1k\n" + card + "\n.op\n.end\n")
    with pytest.raises(NetlistError) as info:
        run_ngspice(tmp_path / "main.cir")
    assert info.value.file == str(tmp_path / "main.cir")
    assert info.value.line == 4 + card.count("\n")
    assert word in info.value.message


@requires_ngspice
@pytest.mark.ngspice
def test_plain_ngspice_reads_a_filesource_file_but_the_runner_refuses(tmp_path):
    """A live read: ngspice 39's filesource takes its waveform from the file named."""
    data = tmp_path / "outside" / "data.txt"
    data.parent.mkdir()
    data.write_text("0 1\n1e-5 3\n")
    work = tmp_path / "work"
    work.mkdir()
    card = f'.model src filesource (file="{data}" amploffset=[0] amplscale=[1])'
    circuit = f"x\na1 %vd([a 0]) src\n{card}\nR1 a 0 1k\n.tran 1u 10u\n"
    (work / "plain.cir").write_text(circuit + ".control\nrun\nprint v(a)[5]\n.endc\n.end\n")
    done = subprocess.run(
        [NGSPICE, "-b", "-n", "plain.cir"], cwd=work, capture_output=True, text=True, timeout=120
    )
    assert "v(a)[5] = 1.0032" in done.stdout  # 1 + 2 * 5 / 3125, between the file's points
    (work / "main.cir").write_text(circuit + ".end\n")
    with pytest.raises(NetlistError) as info:
        run_ngspice(work / "main.cir")
    assert info.value.line == 3
    assert "filesource" in info.value.message


def test_circuit_options_and_file_words_elsewhere_pass(tmp_path):
    """Only option cards and models are read for file names: a node called rawfile, an
    option that names nothing and CIDER's rawfile flag (a format) are fine."""
    from circuitsim.interop.ngspice_deck import flatten_deck

    text = (
        "x\nV1 rawfile 0 DC 1\nR1 rawfile measoutfile 1k\nR2 measoutfile 0 1k\n"
        ".options reltol=1e-4 method=gear filetype=ascii\n"
        ".model n1 numd level=1\n+ output rawfile\n.op\n.end\n"
    )
    lines = flatten_deck(text, "main.cir", tmp_path)
    assert [line.text for line in lines][:4] == text.splitlines()[1:5]


def test_a_dropped_analysis_takes_its_continuation_lines_along():
    """ngspice continues a card on a line whose first character above blank is ``+`` (a
    vertical tab first, too): left behind when its ``.op`` card is dropped, such a line would
    continue the ``.options`` card before it."""
    from circuitsim.interop.ngspice import _deck_lines

    deck = "x\n" + BODY + ".options reltol=1e-3\n.op\n\v+ measoutfile=/tmp/victim.txt\n.end\n"
    text = _with_control(_deck_lines(deck), "tran")
    assert "measoutfile=/tmp" not in text
    assert ".options reltol=1e-3\n" in text


@pytest.fixture
def outside_tmp():
    """A folder outside /tmp (in /var/tmp), removed afterwards."""
    import shutil
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="circuitsim-victim-", dir="/var/tmp"))
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.skipif(not confined(), reason="the kernel has no Landlock: writes are not confined")
def test_the_sandbox_lets_ngspice_write_only_in_its_folder(tmp_path, outside_tmp):
    """The third line of defence: a deck ngspice would let write a file elsewhere (no check of
    ours, no ``set measoutfile``), run through ``run_with_limit``: the file outside /tmp keeps
    its content, a new file in /tmp is not made (files that exist in /tmp stay writable: see
    docs/netlists.md)."""
    victims = [outside_tmp / "victim.txt", tmp_path / "new" / "made.txt"]
    victims[1].parent.mkdir()
    for victim in victims:
        deck = "x\n" + BODY + f".options measoutfile={victim}\n"
        deck += ".control\nrun\nwrite out.raw\n.endc\n.end\n"
        for confine in (False, True):  # unconfined first: the deck is a live attack
            victims[0].write_text(PRECIOUS)
            victims[1].unlink(missing_ok=True)
            folder = tmp_path / f"private-{victim.name}-{confine}"
            folder.mkdir()
            (folder / "deck.cir").write_text(deck)
            done = run_with_limit(
                [NGSPICE, "-b", "-n", "deck.cir"],
                folder,
                bare_environment(folder),
                120,
                confine=confine,
            )
            assert (folder / "out.raw").stat().st_size > 0  # the run itself works
            written = victim.exists() and victim.read_text() != PRECIOUS
            assert written == (not confine), done.stderr
        assert "Could not open file" in done.stderr
