"""Ctrl-C and SIGTERM during numba's compile of the kernels end the CLI at once (exit 130 and
143, one line saying why, no traceback) instead of when the compile is done: a real cold
compile (an empty CIRCUITSIM_CACHE_DIR) stopped a second after its notice; and the watcher
thread alone, for a main thread that cannot run its handler (inside LLVM's C++ code).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from circuitsim.solver.compiled.warmup import WARM_UP_NETLIST

ROOT = Path(__file__).resolve().parents[1]


def _wait_for_line(process: subprocess.Popen, text: str, limit: float = 300.0) -> list[str]:
    """stderr lines up to the first containing ``text`` (the process still running)."""
    lines, deadline = [], time.monotonic() + limit
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return lines
    process.kill()
    raise AssertionError(f"no line with {text!r} on stderr: {''.join(lines)}")


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sent", "code", "word"),
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")],
)
def test_a_signal_during_a_cold_compile_ends_the_run_at_once(tmp_path, sent, code, word):
    pytest.importorskip("numba", reason="numba is not installed: nothing compiles")
    cache = tmp_path / "cache"  # empty: the ports kernel must compile
    netlist = tmp_path / "warm.cir"
    netlist.write_text(WARM_UP_NETLIST)  # every device kind the kernel compiles for
    process = subprocess.Popen(
        [sys.executable, "-m", "circuitsim", "simulate", str(netlist), "--kernel", "ports"],
        cwd=ROOT,
        env={**os.environ, "CIRCUITSIM_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _wait_for_line(process, "warning: compiling the ports kernel")
    time.sleep(1.0)  # inside numba's compiler (tens of seconds on a cold cache)
    process.send_signal(sent)
    _, err = process.communicate(timeout=120)
    assert process.returncode == code, err
    assert f"{word} while numba was compiling the kernels" in err
    assert "Traceback" not in err
    # it ended before the compile did: the compile's time is recorded once it is done
    assert not (cache / "compile-seconds.json").exists()


# A main thread whose SIGINT handler does nothing (as if it sat inside LLVM: the handler would
# run only later), and a thread inside numba's dispatcher (a stand-in of that name, sleeping):
# only the watcher thread can end the process.
WATCHED = """
import signal, sys, threading, time
from circuitsim.cli.interrupt import prompt_during_compile

dispatcher = {"__name__": "numba.core.dispatcher"}
exec("import time\\ndef _compile_for_args():\\n    time.sleep(600)\\n", dispatcher)
with prompt_during_compile():
    signal.signal(signal.SIGINT, lambda signum, frame: None)
    threading.Thread(target=dispatcher["_compile_for_args"], daemon=True).start()
    print("ready", flush=True)
    time.sleep(600)
"""


def test_the_watcher_ends_a_compile_the_main_thread_cannot_interrupt():
    process = subprocess.Popen(
        [sys.executable, "-c", WATCHED],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stdout.readline() == "ready\n"
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130
    assert err.startswith("interrupted while numba was compiling the kernels")


def test_outside_a_compile_ctrl_c_is_a_keyboard_interrupt():
    """No thread in numba's compiler: the handler raises KeyboardInterrupt (finally blocks
    run), and the previous handler is back afterwards."""
    from circuitsim.cli.interrupt import compiling, prompt_during_compile

    before = signal.getsignal(signal.SIGINT)
    assert not compiling()
    with pytest.raises(KeyboardInterrupt), prompt_during_compile():
        signal.raise_signal(signal.SIGINT)
        time.sleep(5)  # not reached: the handler raises first
    assert signal.getsignal(signal.SIGINT) is before
