"""ngspice's private folder, environment, time limit and clean-up (issue 21: runner hygiene).

Killed runs must not leave ``circuitsim-ngspice-*`` folders or ngspice processes behind:
SIGTERM and SIGINT clean up at once, SIGKILL at the next run.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from circuitsim.interop import ngspice
from circuitsim.interop.errors import NgspiceError, NgspiceTimeout
from circuitsim.interop.ngspice import FOLDER_PREFIX, run_ngspice
from circuitsim.interop.sandbox import (
    bare_environment,
    private_folder,
    remove_stale_folders,
    run_with_limit,
)
from tests.conftest import dead_pid, requires_ngspice

ROOT = Path(__file__).resolve().parents[2]
# Two million time steps (the step limit: a longer run is refused before ngspice starts):
# ngspice is still busy, for seconds, when the tests stop it.
SLOW = "slow\nV1 a 0 SIN(0 1 1meg)\nR1 a 0 1k\n.tran 1n 2m 0 1n\n.end\n"
QUICK = "divider\nV1 a 0 DC 1\nR1 a b 1k\nR2 b 0 1k\n.op\n.end\n"


def _running(pid: int) -> bool:
    """The process exists and is not a zombie (PID 1 of a container may never reap it)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def _start_cli_run(tmp_path: Path) -> tuple[subprocess.Popen, Path, int]:
    """``circuitsim simulate --engine ngspice`` on SLOW, once ngspice is running in its folder.

    Returns the CLI process, ngspice's private folder and ngspice's process id.
    """
    temp = tmp_path / "tmp"
    temp.mkdir()
    netlist = tmp_path / "slow.cir"
    netlist.write_text(SLOW)
    process = subprocess.Popen(
        [sys.executable, "-m", "circuitsim", "simulate", str(netlist), "--engine", "ngspice"],
        cwd=ROOT,
        env={**os.environ, "TMPDIR": str(temp), "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        children = list(temp.glob(f"{FOLDER_PREFIX}{process.pid}-*/.child"))
        if children and children[0].read_text():
            return process, children[0].parent, int(children[0].read_text())
        assert process.poll() is None, process.communicate()
        time.sleep(0.05)
    process.kill()
    raise AssertionError("ngspice did not start within 120 s")


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize(
    ("sent", "code", "word"),
    [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")],
)
def test_a_stopped_cli_run_removes_its_folder_and_ngspice(tmp_path, sent, code, word):
    process, folder, child = _start_cli_run(tmp_path)
    assert _running(child)
    process.send_signal(sent)
    _, err = process.communicate(timeout=60)
    assert process.returncode == code and word in err
    assert not folder.exists()
    assert not _running(child)


@requires_ngspice
@pytest.mark.ngspice
def test_a_killed_run_is_cleaned_up_by_the_next(tmp_path, monkeypatch):
    process, folder, child = _start_cli_run(tmp_path)
    process.kill()  # SIGKILL: no clean-up of its own
    process.communicate(timeout=60)
    assert folder.exists()  # what the issue saw (ngspice may live on too, or die of SIGPIPE)
    monkeypatch.setattr(tempfile, "tempdir", str(folder.parent))
    assert run_ngspice(QUICK)["v(b)"][0] == pytest.approx(0.5, rel=1e-9)
    assert not folder.exists()
    deadline = time.monotonic() + 10
    while _running(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _running(child)
    assert list(folder.parent.iterdir()) == []  # and the quick run's own folder is gone


HOLDER = """
import sys, time
from circuitsim.interop.sandbox import private_folder

with private_folder("t-", sys.argv[1]) as folder:
    print(folder, flush=True)
    time.sleep(600)
"""


def test_a_folder_in_use_is_never_removed(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(tmp_path)],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        text=True,
    )
    folder = Path(holder.stdout.readline().strip())
    assert folder.name.startswith(f"t-{holder.pid}-")
    old = time.time() - 3600
    os.utime(folder, (old, old))  # its age does not matter while its lock is held
    assert remove_stale_folders("t-", str(tmp_path)) == [] and folder.is_dir()
    holder.kill()
    holder.wait(timeout=60)
    assert remove_stale_folders("t-", str(tmp_path)) == [folder]


def test_unlocked_folders_go_once_their_process_is_gone(tmp_path):
    dead = dead_pid()
    live = os.getppid()
    for name in (f"t-{dead}-a", f"t-{live}-b", f"t-{live}-c", f"t-{os.getpid()}-d"):
        (tmp_path / name).mkdir()
    (tmp_path / f"t-{live}-c" / ".lock").touch()  # unlocked, and a minute old: a reused pid
    old = time.time() - 120
    os.utime(tmp_path / f"t-{live}-c", (old, old))
    (tmp_path / "t-notapid").mkdir()  # not named by the sandbox: never touched
    removed = remove_stale_folders("t-", str(tmp_path))
    assert sorted(p.name for p in removed) == sorted([f"t-{dead}-a", f"t-{live}-c"])
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([f"t-{live}-b", f"t-{os.getpid()}-d", "t-notapid"])


def test_an_orphan_working_in_a_stale_folder_is_killed(tmp_path):
    dead = dead_pid()
    folder, reused = (
        tmp_path / f"t-{dead}-x",
        tmp_path / f"t-{dead}-y",
    )
    for stale in (folder, reused):
        stale.mkdir()
        (stale / ".lock").touch()
    orphan = subprocess.Popen(["sleep", "600"], cwd=folder, start_new_session=True)
    # a process id in .child now used by a program working elsewhere: left alone
    bystander = subprocess.Popen(["sleep", "600"], cwd=tmp_path, start_new_session=True)
    try:
        (folder / ".child").write_text(str(orphan.pid))
        (reused / ".child").write_text(str(bystander.pid))
        assert sorted(remove_stale_folders("t-", str(tmp_path))) == [folder, reused]
        assert orphan.wait(timeout=10) == -signal.SIGKILL
        assert bystander.poll() is None
    finally:
        bystander.kill()
        orphan.kill()
        bystander.wait()


def test_the_folder_goes_on_any_exception(tmp_path):
    with pytest.raises(KeyboardInterrupt), private_folder("t-", str(tmp_path)) as folder:
        (folder / "deck.cir").write_text("x")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_the_environment_is_bare(tmp_path, monkeypatch):
    monkeypatch.setenv("SPICE_SCRIPTS", "/somewhere")
    monkeypatch.setenv("NGSPICE_INPUT_DIR", "/somewhere")
    monkeypatch.setenv("SECRET_TOKEN", "x")
    env = bare_environment(tmp_path)
    assert set(env) <= {"PATH", "HOME", "TMPDIR", "LC_ALL", "LD_LIBRARY_PATH"}
    assert env["HOME"] == str(tmp_path) and env["LC_ALL"] == "C"
    done = run_with_limit(["env"], tmp_path, env, timeout=30)
    seen = dict(line.split("=", 1) for line in done.stdout.splitlines() if "=" in line)
    assert not any(k.startswith(("SPICE", "NGSPICE", "SECRET")) for k in seen)
    assert seen["HOME"] == str(tmp_path)


@requires_ngspice
@pytest.mark.ngspice
def test_ngspice_is_started_without_init_files_in_its_own_folder(tmp_path, monkeypatch):
    seen = {}

    def spy(args, cwd, env, timeout, watch=None):
        seen.update(args=args, cwd=cwd, env=env, deck=(cwd / args[-1]).read_text())
        return run_with_limit(args, cwd, env, timeout, watch)

    monkeypatch.setattr(ngspice, "run_with_limit", spy)
    monkeypatch.chdir(tmp_path)
    run_ngspice(QUICK)
    assert seen["args"][1:] == ["-b", "-n", "deck.cir"]
    assert seen["cwd"].name.startswith(f"{FOLDER_PREFIX}{os.getpid()}-")
    assert seen["cwd"] != tmp_path and seen["env"]["HOME"] == str(seen["cwd"])
    assert seen["deck"].splitlines()[0] == "circuitsim deck for ngspice"


@requires_ngspice
@pytest.mark.ngspice
def test_timeout_is_a_named_error_and_leaves_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    started = time.monotonic()
    with pytest.raises(NgspiceTimeout) as info:
        run_ngspice(SLOW, timeout=0.5)
    assert time.monotonic() - started < 30
    assert isinstance(info.value, NgspiceError) and info.value.seconds == 0.5
    assert "did not finish within 0.5 s" in str(info.value) and "TMAX" in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_only_the_sandbox_starts_programs():
    """Every external program (ngspice) starts through interop/sandbox.py's run_with_limit."""
    package = ROOT / "circuitsim"
    starts = re.compile(
        r"^\s*(import|from)\s+(subprocess|pty|multiprocessing)\b"
        r"|\bos\.(system|popen|exec\w*|spawn\w*|posix_spawn\w*|fork\w*)\(",
        re.MULTILINE,
    )
    found = [
        str(path.relative_to(ROOT))
        for path in package.rglob("*.py")
        if starts.search(path.read_text())
    ]
    assert found == ["circuitsim/interop/sandbox.py"]
    callers = [
        str(path.relative_to(ROOT))
        for path in package.rglob("*.py")
        if "run_with_limit" in path.read_text()
    ]
    assert sorted(callers) == ["circuitsim/interop/ngspice.py", "circuitsim/interop/sandbox.py"]


@requires_ngspice
@pytest.mark.ngspice
def test_cli_ngspice_timeout_option(tmp_path, capsys):
    from circuitsim.cli import main

    netlist = tmp_path / "slow.cir"
    netlist.write_text(SLOW)
    argv = ["simulate", str(netlist), "--engine", "ngspice", "--ngspice-timeout"]
    assert main([*argv, "0.5"]) == 3  # the run failed
    err = capsys.readouterr().err
    assert "ngspice did not finish within 0.5 s and was stopped" in err
    assert "--ngspice-timeout SECONDS" in err
    assert main([*argv, "0"]) == 2
    assert "--ngspice-timeout must be a positive finite number, got 0" in capsys.readouterr().err


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize(
    "argv",
    [
        ["compare", "--engine", "ngspice", "--tstop", "0.3"],
        [
            "sweep",
            "--engine",
            "ngspice",
            "--param",
            "speed",
            "--values",
            "54:55:1",
            "--tstop",
            "0.3",
            "--window",
            "0.1",
        ],
    ],
    ids=["compare", "sweep"],
)
def test_other_verbs_run_ngspice_in_the_sandbox(argv, tmp_path, monkeypatch, capsys):
    """compare and sweep reach ngspice through run_ngspice (reproduce does so through
    compare.case.run_engine, as compare does)."""
    from circuitsim.cli import main

    calls = []

    def spy(args, cwd, env, timeout, watch=None):
        calls.append((args[1:], cwd.name, (cwd / args[-1]).read_text().splitlines()[0]))
        return run_with_limit(args, cwd, env, timeout, watch)

    monkeypatch.setattr(ngspice, "run_with_limit", spy)
    extra = ["--out", str(tmp_path)] if argv[0] == "sweep" else []
    assert main([*argv, *extra]) == 0
    capsys.readouterr()
    assert len(calls) == (1 if argv[0] == "compare" else 2)
    for args, folder, title in calls:
        assert args == ["-b", "-n", "deck.cir"] and folder.startswith(FOLDER_PREFIX)
        assert title == "circuitsim deck for ngspice"


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize(
    "verb",
    [
        ["compare", "--engine", "ngspice"],
        ["sweep", "--param", "speed", "--values", "55", "--engine", "ngspice", "--out", "{out}"],
    ],
    ids=["compare", "sweep"],
)
def test_cli_ngspice_timeout_reaches_compare_and_sweep(verb, tmp_path, capsys):
    """compare and sweep stop ngspice after --ngspice-timeout (not the 300 s default): the
    wheelset's 5 s run takes ngspice well over 0.05 s, so the limit is what ends it."""
    from circuitsim.cli import main

    argv = [part.format(out=tmp_path) for part in verb]
    assert main([*argv, "--ngspice-timeout", "0.05"]) == 3  # the run failed
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if ": error:" in line]
    assert len(errors) == 1  # one line says what happened; ngspice's last lines follow it
    assert f"circuitsim {verb[0]}: error: ngspice did not finish within 0.05 s" in errors[0]
    assert "--ngspice-timeout SECONDS" in errors[0]
    assert main([*argv, "--ngspice-timeout", "0"]) == 2
    assert "--ngspice-timeout must be a positive finite number, got 0" in capsys.readouterr().err


@requires_ngspice
@pytest.mark.ngspice
def test_reproduce_passes_ngspice_timeout(tmp_path):
    """reproduce's ngspice rows are stopped at its ngspice_timeout, a failed row naming it."""
    from circuitsim.studies.reproduce import PAPER_SCENARIOS, reproduce

    result = reproduce(
        tmp_path,
        scenarios=PAPER_SCENARIOS[:1],
        opamps=("ideal",),
        series=("exact",),
        engines=("ngspice",),
        free_speeds=(),
        hunting_speeds=(),
        frequency_response=False,
        workers=1,
        ngspice_timeout=0.05,
    )
    [row] = result.rows
    assert row.status.startswith("failed: NgspiceTimeout: ngspice did not finish within 0.05 s")
