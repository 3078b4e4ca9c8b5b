"""A writer killed with SIGKILL leaves its ``.NAME.<pid>-<random>.tmp``; the next write of the
same file removes it once its process is gone and it has not changed for an hour (issue 21)."""

import os
import subprocess
import sys
import time
from pathlib import Path

from circuitsim.atomic import remove_leftovers, write_text_atomic
from tests.conftest import dead_pid

ROOT = Path(__file__).resolve().parents[1]

# Writes half of out.csv's new content, then waits to be killed.
WRITER = """
import sys, time
from circuitsim.atomic import write_atomic

def write(handle):
    handle.write("half of the new content\\n")
    handle.flush()
    print("writing", flush=True)
    time.sleep(600)

write_atomic(sys.argv[1], write)
"""


def _age(path: Path, seconds: float) -> None:
    then = time.time() - seconds
    os.utime(path, (then, then))


def test_a_killed_writer_leaves_the_old_file_and_the_next_write_cleans_up(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old\n")
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(target)],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        text=True,
    )
    assert writer.stdout.readline() == "writing\n"
    writer.kill()
    writer.wait(timeout=60)
    leftovers = list(tmp_path.glob(".out.csv.*.tmp"))
    assert target.read_text() == "old\n" and len(leftovers) == 1
    assert leftovers[0].name.startswith(f".out.csv.{writer.pid}-")

    write_text_atomic(target, "new\n")  # within the hour: the leftover may be a live writer's
    assert leftovers[0].exists()
    _age(leftovers[0], 2 * 3600)
    write_text_atomic(target, "newer\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]
    assert target.read_text() == "newer\n"


def test_only_leftovers_of_dead_processes_and_of_that_file_go(tmp_path):
    gone = dead_pid()
    names = [
        f".a.txt.{gone}-0123abcd.tmp",  # goes
        f".a.txt.{os.getppid()}-0123abcd.tmp",  # a live process: stays
        f".a.txt.{os.getpid()}-0123abcd.tmp",  # this process: stays
        f".b.txt.{gone}-0123abcd.tmp",  # another file's: stays
        f".a.txt.{gone}-0123abcd.tmp.keep",  # not our pattern: stays
        ".a.txt.0123abcd.tmp",  # the old pattern without a pid: stays (no owner to check)
    ]
    for name in names:
        (tmp_path / name).write_text("x")
        _age(tmp_path / name, 2 * 3600)
    assert remove_leftovers(tmp_path / "a.txt") == [str(tmp_path / names[0])]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names[1:])
