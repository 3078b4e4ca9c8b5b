"""Shared test fixtures: the ngspice referee and temporary output folders."""

import os
import shutil

import pytest

# the start-up library (solver/jit.py) is neither used nor built by the tests' processes: each
# runs numba's kernels, as a process without a library does (the same in CI and on a machine
# with a library); tests/solver/test_startup_library.py builds one and runs processes on it
os.environ.setdefault("CIRCUITSIM_NO_STARTUP_LIBRARY", "1")

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
