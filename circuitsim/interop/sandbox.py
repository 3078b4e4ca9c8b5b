"""Running another program on our files only: a private folder, a bare environment, a time limit.

Three pieces, used by :mod:`circuitsim.interop.ngspice`:

* :func:`private_folder` makes a temporary folder named ``<prefix><pid>-<random>`` and holds
  an exclusive ``flock`` on a ``.lock`` file in it while it is in use; the folder is removed
  when the block ends, also on an exception (KeyboardInterrupt, or the SystemExit the CLI makes
  of SIGTERM). A process killed with SIGKILL cannot clean up, but the kernel releases its lock,
  so the next run removes the folders of that prefix whose lock it can take and whose process
  is gone (:func:`remove_stale_folders`): a folder in use is never touched, not even by a
  process in another PID namespace sharing ``/tmp``, since its lock is held.
* :func:`bare_environment`: only what a program needs to start (``PATH``, the dynamic
  loader's ``LD_LIBRARY_PATH`` if set), ``HOME`` pointing into the private folder, the C
  locale; nothing else of the user's environment reaches it.
* :func:`run_with_limit` starts the program in its own session (process group), with stdin
  closed and its output captured, and kills the whole group when the time limit passes or
  when the caller is interrupted. Its process id goes into the folder (``.child``): should the
  caller be killed with SIGKILL, the next clean-up kills that orphan too (on Linux, where
  ``/proc/<pid>/cwd`` confirms it is still the program working in that folder). Where the
  kernel has Landlock, the program may change nothing outside its working folder and open no
  TCP connection (:mod:`circuitsim.interop.confine`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from circuitsim.interop.confine import landlock_abi, write_confinement

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no flock, stale folders are left alone
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "private_folder",
    "remove_stale_folders",
    "bare_environment",
    "run_with_limit",
    "confined",
]

_LOCK = ".lock"
_CHILD = ".child"  # the process id of the program running in the folder
_SETTLING_SECONDS = 60.0  # an unlocked folder of a live pid this old is no longer being set up


@contextlib.contextmanager
def private_folder(prefix: str, parent: str | None = None) -> Iterator[Path]:
    """A new folder only this process uses, removed when the block ends.

    Parameters
    ----------
    prefix : str
        Start of the folder's name (``"circuitsim-ngspice-"``); the process id and a random
        part follow.
    parent : str, optional
        Where to make it; default the system's temporary folder.

    Yields
    ------
    Path
        The folder (mode 0700), empty but for its ``.lock`` file.
    """
    parent = parent or tempfile.gettempdir()
    remove_stale_folders(prefix, parent)
    folder = Path(tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-", dir=parent))
    lock = None
    try:
        lock = open(folder / _LOCK, "wb")  # noqa: SIM115 - held open for the whole block
        if fcntl is not None:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        if lock is not None:
            lock.close()


def remove_stale_folders(prefix: str, parent: str | None = None) -> list[Path]:
    """Remove folders ``<prefix><pid>-*`` that no live process holds; return them.

    A folder is stale when its ``.lock`` file can be locked (no process holds it) and its
    process is gone (e.g. killed with SIGKILL) or, with the process id in use again, it has
    not changed for a minute; or when it has no ``.lock`` file and its process is gone
    (killed between making the folder and locking it). A locked folder, a folder of this
    process, another user's folder or a name this module did not make is never touched.
    """
    if fcntl is None:
        return []
    parent_path = Path(parent or tempfile.gettempdir())
    removed = []
    try:
        candidates = list(parent_path.glob(f"{prefix}*"))
    except OSError:
        return []
    for folder in candidates:
        with contextlib.suppress(OSError):
            info = folder.lstat()
            if not folder.is_dir() or folder.is_symlink() or info.st_uid != os.getuid():
                continue
            if _abandoned(folder, prefix):
                _stop_orphan(folder)
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(folder)
    return removed


def _abandoned(folder: Path, prefix: str) -> bool:
    """No live process uses ``folder`` (see :func:`remove_stale_folders`)."""
    pid_text, dash, _ = folder.name[len(prefix) :].partition("-")
    if not (pid_text.isdigit() and dash) or int(pid_text) == os.getpid():
        return False  # not named by this module, or ours (another thread may be using it)
    owner_gone = not _alive(int(pid_text))
    lock_path = folder / _LOCK
    if not lock_path.exists():
        return owner_gone  # killed between making the folder and locking it
    with open(lock_path, "rb") as lock:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
    # Unlocked: its process ended, or has only just made the folder and not locked it yet
    # (then the pid is alive and the folder new); a reused pid is outlived by the age test.
    return owner_gone or time.time() - folder.stat().st_mtime > _SETTLING_SECONDS


def _stop_orphan(folder: Path) -> None:
    """Kill the program a dead process left running in ``folder`` (its own process group).

    Only a process whose working folder is ``folder`` is killed (``/proc/<pid>/cwd``), so a
    process id reused since by an unrelated program is left alone.
    """
    with contextlib.suppress(OSError, ValueError):
        pid = int((folder / _CHILD).read_text())
        cwd = os.readlink(f"/proc/{pid}/cwd")
        if cwd in (str(folder), f"{folder} (deleted)"):
            os.killpg(pid, signal.SIGKILL)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def bare_environment(home: Path) -> dict[str, str]:
    """The environment a batch program gets: no variables of ours or the user's beyond these.

    Parameters
    ----------
    home : Path
        Given as ``HOME`` (the private folder: no start-up files of the user's are found).

    Returns
    -------
    dict of str to str
        ``PATH`` (the caller's, or the system default), ``LD_LIBRARY_PATH`` when set (a
        program installed outside the system folders needs it to start), ``HOME``,
        ``TMPDIR`` (``home``) and ``LC_ALL=C`` (numbers read and written with a dot).
    """
    env = {
        "PATH": os.environ.get("PATH", os.defpath),
        "HOME": str(home),
        "TMPDIR": str(home),
        "LC_ALL": "C",
    }
    if os.environ.get("LD_LIBRARY_PATH"):
        env["LD_LIBRARY_PATH"] = os.environ["LD_LIBRARY_PATH"]
    if os.environ.get("SYSTEMROOT"):  # Windows programs do not start without it
        env["SYSTEMROOT"] = os.environ["SYSTEMROOT"]
    return env


@dataclass(frozen=True)
class Finished:
    """How a program run ended: exit status and its output (text, undecodable bytes replaced)."""

    returncode: int
    stdout: str
    stderr: str


class TimeLimitExceeded(Exception):
    """The program ran past its time limit and was killed; ``output`` holds what it printed."""

    def __init__(self, output: str):
        self.output = output
        super().__init__("time limit exceeded")


WATCH_SECONDS = 1.0
"""A watched program is looked at about this often (``run_with_limit``'s ``watch``), s."""


def run_with_limit(
    args: list[str],
    cwd: Path,
    env: dict[str, str],
    timeout: float,
    watch: Callable[[int, float], None] | None = None,
    confine: bool = True,
) -> Finished:
    """Run ``args`` in ``cwd`` with ``env``; kill it (and its children) after ``timeout`` s.

    ``watch``, if given, is called about every :data:`WATCH_SECONDS` while the program runs,
    with its process id and the seconds since its start; an exception it raises kills the
    program and propagates. With ``confine`` (the default) the program may change the file
    system beneath ``cwd`` only and open no TCP connection, where the kernel has Landlock
    (:func:`~circuitsim.interop.confine.write_confinement`; :func:`confined` says whether).

    Raises
    ------
    TimeLimitExceeded
        The time limit passed; the process group was killed.
    OSError
        The program could not be started, or not confined where the kernel offers it.
    """
    # ngspice copies its input into a tmpfile() first, which glibc opens (O_TMPFILE) in /tmp
    # whatever TMPDIR says: writing to files there stays allowed, making entries does not
    tmp = tuple(Path(p) for p in ("/tmp",) if os.path.isdir(p))
    confinement = write_confinement(cwd, tmp) if confine else None
    restrict, ruleset = confinement if confinement is not None else (None, None)
    try:
        process = subprocess.Popen(
            args,
            cwd=cwd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=os.name == "posix",
            preexec_fn=restrict,  # noqa: PLW1509 - prepared in the parent, two system calls
            pass_fds=() if ruleset is None else (ruleset,),
        )
    except subprocess.SubprocessError as exc:  # the child could not restrict itself
        raise OSError(f"cannot confine {args[0]} to its folder: {exc}") from None
    finally:
        if ruleset is not None:
            os.close(ruleset)
    try:
        (cwd / _CHILD).write_text(str(process.pid))  # for remove_stale_folders, should we die
        out, err = _communicate(process, timeout, watch)
    except subprocess.TimeoutExpired:
        _kill(process)
        out, err = process.communicate()
        raise TimeLimitExceeded(_text(out) + _text(err)) from None
    except BaseException:  # KeyboardInterrupt, SystemExit from SIGTERM: stop it, then go on
        _kill(process)
        process.wait()
        raise
    finally:
        if process.returncode is None:
            _kill(process)
            process.wait()
    return Finished(process.returncode, _text(out), _text(err))


def confined() -> bool:
    """True where :func:`run_with_limit` confines a program's writes (the kernel has Landlock)."""
    return landlock_abi() >= 1


def _communicate(process: subprocess.Popen, timeout: float, watch) -> tuple[bytes, bytes]:
    """``process.communicate(timeout=timeout)``, calling ``watch`` in between (no output is
    lost by a ``communicate`` that timed out and is called again)."""
    if watch is None:
        return process.communicate(timeout=timeout)
    started = time.monotonic()
    interval = 0.1 * WATCH_SECONDS  # the first look soon after the start
    while True:
        left = timeout - (time.monotonic() - started)
        try:
            return process.communicate(timeout=max(min(left, interval), 0.0))
        except subprocess.TimeoutExpired:
            if time.monotonic() - started >= timeout:
                raise
            watch(process.pid, time.monotonic() - started)
            interval = WATCH_SECONDS


def _kill(process: subprocess.Popen) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError, OSError):
        if os.name == "posix":
            os.killpg(process.pid, signal.SIGKILL)
        else:  # pragma: no cover
            process.kill()


def _text(data: bytes | None) -> str:
    return data.decode(errors="replace") if data else ""
