"""circuitsim.inputfile: a user's file is read with a size limit that no reported size can fool.

The limit holds for a regular file past it (refused before any byte is read), for files that
report 0 bytes but hold more (/proc), for a device that never ends (/dev/zero) and for a FIFO
whose writer never stops; and every read of a user's file in the package goes through it.
"""

import errno
import os
import re
import threading
from pathlib import Path

import numpy as np
import pytest

from circuitsim import inputfile
from circuitsim.compare.signals import dominant_frequency, nrmsd_percent, phase_lag
from circuitsim.inputfile import InputTooLargeError, read_bytes, read_text, size_words

PACKAGE = Path(__file__).resolve().parents[1] / "circuitsim"


def test_a_file_within_the_limit_is_read_whole(tmp_path):
    path = tmp_path / "a.txt"
    path.write_bytes(b"x" * 100)
    assert read_bytes(path, 100) == b"x" * 100


def test_text_is_decoded_as_open_would(tmp_path):
    path = tmp_path / "a.txt"
    path.write_bytes("a\r\nb\rc\n\u00e9".encode())
    assert read_text(path, 100) == "a\nb\nc\n\u00e9"
    assert read_text(path, 100, newline="") == "a\r\nb\rc\n\u00e9"
    path.write_bytes(b"\xff")
    with pytest.raises(UnicodeDecodeError):
        read_text(path, 100)


def test_a_regular_file_past_the_limit_is_refused_with_its_size(tmp_path):
    path = tmp_path / "big.toml"
    path.write_bytes(b"x" * 101)
    with pytest.raises(InputTooLargeError) as caught:
        read_bytes(path, 100, "a model file")
    error = caught.value
    assert isinstance(error, OSError) and error.errno == errno.EFBIG
    assert error.size == 101 and error.limit == 100
    assert str(error) == f"{path}: too large: 101 bytes (a model file is at most 100 bytes)"


def test_a_file_that_reports_no_size_is_still_bounded():
    """/proc files are regular files of st_size 0; their content is longer than 10 bytes."""
    assert os.stat("/proc/self/maps").st_size == 0
    with pytest.raises(InputTooLargeError) as caught:
        read_bytes("/proc/self/maps", 10)
    assert caught.value.size is None
    assert "more than 10 bytes" in str(caught.value)


def test_dev_zero_is_refused_after_limit_plus_one_bytes():
    with pytest.raises(InputTooLargeError) as caught:
        read_bytes("/dev/zero", 2**20, "a netlist file")
    assert str(caught.value) == (
        "/dev/zero: too large: more than 1 MiB (a netlist file is at most 1 MiB)"
    )


def _endless_writer(fifo: Path, written: list[int]) -> threading.Thread:
    """A thread writing to ``fifo`` until its reader goes away (EPIPE)."""

    def write() -> None:
        fd = os.open(fifo, os.O_WRONLY)
        try:
            while True:
                written[0] += os.write(fd, b"\0" * 65536)
        except BrokenPipeError:
            pass
        finally:
            os.close(fd)

    thread = threading.Thread(target=write, daemon=True)
    thread.start()
    return thread


def test_a_fifo_whose_writer_never_stops_is_refused(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    written = [0]
    writer = _endless_writer(fifo, written)
    with pytest.raises(InputTooLargeError):
        read_bytes(fifo, 100_000)
    writer.join(timeout=30)
    assert not writer.is_alive()
    assert written[0] < 100_000 + 2 * 65536 + 65536 * 16  # the pipe's buffer, not more


def test_a_fifo_within_the_limit_is_read(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)

    def write() -> None:
        with open(fifo, "wb") as handle:
            handle.write(b"time,value\n0,1\n")

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    assert read_text(fifo, 1000) == "time,value\n0,1\n"
    writer.join(timeout=30)


def test_missing_files_and_folders_stay_os_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_bytes(tmp_path / "none", 10)
    with pytest.raises(IsADirectoryError):
        read_bytes(tmp_path, 10)


@pytest.mark.parametrize(
    "size, words",
    [(16 * 2**20, "16 MiB"), (2**31, "2 GiB"), (4096, "4 KiB"), (1000, "1,000 bytes")],
)
def test_limits_in_words(size, words):
    assert size_words(size) == words


def test_the_limits_table_in_the_docs_is_current():
    """docs/robustness.md lists every *_BYTES limit with its value in words."""
    text = (PACKAGE.parent / "docs" / "robustness.md").read_text()
    for name in dir(inputfile):
        if name.endswith("_BYTES"):
            words = size_words(getattr(inputfile, name))
            assert f"| {words} | `{name}` |" in text, name
    assert f"| {inputfile.MAX_SCALE_STATES:,} | `MAX_SCALE_STATES` |" in text


# Reads that are not of a user's file: each file that reads without the helper, and why.
INTERNAL_READS = {
    "interop/sandbox.py": "the lock and child-PID files of our own private folder",
    "netlist/library.py": "the part library shipped in the package",
    "solver/threads.py": "/proc/self/maps",
    "solver/jit.py": "the package's own sources, numba's version file, /proc/cpuinfo, the cache",
    "solver/compiled/startup_library.py": "the compile log we write",
    "solver/compiled/cache.py": "the kernel cache's stamps and timings we write",
    "solver/waveforms.py": "np.loadtxt of text read_text has already bounded",
    "cli/bench_verbs.py": "webbrowser.open, not a file",
    "cli/__init__.py": "os.open of the null device for writing",
    "interop/confine.py": "os.open of the private folder as a Landlock rule's handle",
    "interop/ngspice_limits.py": "/proc/PID/status of the ngspice process we started",
}
_READ = re.compile(
    r"\bopen\(|\.read_text\(|\.read_bytes\(|np\.loadtxt\(|np\.genfromtxt\(|np\.load\(|"
    r"json\.load\(|tomllib\.load\(|csv\.reader\(open"
)


def test_every_user_file_is_read_through_the_helper():
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE).as_posix()
        if name in ("inputfile.py", "atomic.py"):
            continue
        for number, line in enumerate(path.read_text().splitlines(), start=1):
            if _READ.search(line.split("#", 1)[0]):
                found.setdefault(name, []).append(number)
    unexplained = {name: lines for name, lines in found.items() if name not in INTERNAL_READS}
    assert not unexplained, f"reads without circuitsim.inputfile: {unexplained}"


# --- trace measures at any finite magnitude ----------------------------------------------


def test_trace_measures_do_not_depend_on_the_magnitude():
    """A finite trace of 1e300 (a raw file's value) measures as the same trace at 1."""
    t = np.linspace(0.0, 2.0, 2001)
    reference = np.sin(2 * np.pi * 3.0 * t)
    late = np.sin(2 * np.pi * 3.0 * (t - 0.01))
    assert dominant_frequency(t, 1e300 * reference) == pytest.approx(
        dominant_frequency(t, reference), rel=1e-12
    )
    assert dominant_frequency(t, reference) == pytest.approx(3.0, rel=1e-3)
    assert phase_lag(t, 1e300 * reference, 1e300 * late) == pytest.approx(0.01, rel=1e-6)
    assert nrmsd_percent(reference, 1e300 * reference) == pytest.approx(
        100 * (1e300 - 1) * np.sqrt(0.5) / 2.0, rel=1e-3
    )


# --- raw files: a seeded mutation run -----------------------------------------------------


def _raw_samples() -> list[bytes]:
    """A binary, an ASCII, a complex and an LTspice-style raw file of 3 points."""
    header = (
        "Title: t\nDate: d\nPlotname: Transient Analysis\nFlags: {flags}\n"
        "No. Variables: 2\nNo. Points: 3\nVariables:\n\t0\ttime\ttime\n\t1\tv(a)\tvoltage\n"
    )
    rows = np.array([[0.0, 1.0], [1e-3, 2.0], [2e-3, 3.0]])
    binary = header.format(flags="real").encode() + b"Binary:\n" + rows.tobytes()
    ascii_ = (
        header.format(flags="real")
        + "Values:\n"
        + "".join(f" {k}\t{t!r}\n\t{v!r}\n" for k, (t, v) in enumerate(rows.tolist()))
    )
    complex_ = header.format(flags="complex").replace("time\ttime", "frequency\tfrequency")
    complex_ += "Values:\n" + "".join(f" {k}\t{k + 1}.0,0.0\n\t1.0,-1.0\n" for k in range(3))
    ltspice = header.format(flags="real forward").encode("utf_16_le") + "Binary:\n".encode(
        "utf_16_le"
    )
    ltspice += b"".join(np.float64(t).tobytes() + np.float32(v).tobytes() for t, v in rows.tolist())
    return [binary, ascii_.encode(), complex_.encode(), b"\xff\xfe" + ltspice]


_HOSTILE_FIELDS = [b"-1", b"0", b"-0", b"1e3", b"99999999999999999999999", b"x", b"", b"2.5",
                   b"1" * 5000, b"1000000000"]  # fmt: skip


def _mutate(data: bytes, rng: np.random.Generator) -> bytes:
    choice = rng.integers(6)
    if choice == 0:  # a header count replaced
        key = [b"No. Points: 3", b"No. Variables: 2"][rng.integers(2)]
        if key in data:
            return data.replace(key, key.split(b":")[0] + b": " + rng.choice(_HOSTILE_FIELDS))
    if choice == 1:  # cut anywhere
        return data[: rng.integers(len(data) + 1)]
    if choice == 2 and data:  # bytes overwritten
        out = bytearray(data)
        for _ in range(rng.integers(1, 8)):
            out[rng.integers(len(out))] = rng.integers(256)
        return bytes(out)
    if choice == 3:  # a value made huge or non-finite in the text
        return data.replace(b"2.0", rng.choice([b"1e300", b"nan", b"inf", b"1" * 401, b"1e999"]))
    if choice == 4:  # a line deleted or duplicated
        lines = data.split(b"\n")
        k = rng.integers(len(lines))
        lines[k : k + 1] = [] if rng.integers(2) else [lines[k], lines[k]]
        return b"\n".join(lines)
    return data + bytes(rng.integers(256, size=rng.integers(1, 64), dtype=np.uint8))


def test_mutated_raw_files_end_in_waveforms_or_a_named_error():
    """600 seeded mutations: every one parses, or raises NgspiceError (never another error)."""
    from circuitsim.interop.errors import NgspiceError
    from circuitsim.interop.rawfile import parse_rawfile

    rng = np.random.default_rng(43)
    samples = _raw_samples()
    for sample in samples:
        assert len(parse_rawfile(sample).time) == 3
    outcomes = {"parsed": 0, "named": 0}
    for _ in range(600):
        data = samples[rng.integers(len(samples))]
        for _ in range(rng.integers(1, 3)):
            data = _mutate(data, rng)
        try:
            waves = parse_rawfile(data)
        except NgspiceError:
            outcomes["named"] += 1
            continue
        outcomes["parsed"] += 1
        for values in (waves.time, *waves.signals.values()):
            assert np.all(np.isfinite(values))
    assert outcomes["parsed"] > 0 and outcomes["named"] > 0
