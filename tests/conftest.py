"""Shared test fixtures: the ngspice referee and temporary output folders."""

import shutil

import pytest

NGSPICE = shutil.which("ngspice")

requires_ngspice = pytest.mark.skipif(
    NGSPICE is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def dead_pid() -> int:
    """The process id of a process that has just ended (no process of that id runs now)."""
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    return int(done.stdout)
