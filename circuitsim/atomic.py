"""Writing files without ever leaving a half-written one: temporary name, then rename.

A leaf module (imports nothing of ours), usable from every room and the CLI.

The data goes to a hidden temporary file beside the target (``.NAME.<pid>-<random>.tmp``), which
is renamed over the target only once it is complete, so a reader sees the old file or the new
one, never a mix, and a failed write leaves the old file as it was. On top of the bare recipe:

* permissions: a new file gets what an ordinary ``open(path, "w")`` would give (0666 less the
  umask, applied by the kernel when the temporary file is created with mode 0666, so the umask
  is never read or changed); an existing file keeps its permission bits. Its owner and group
  are those of the writing user (only root could keep them);
* symbolic links: a link is followed and its final target replaced, the link stays a link;
* special files (``/dev/null``, a FIFO, a terminal) cannot be renamed over and are written in
  place, as ``open`` would;
* errors: an :class:`OSError` subclass naming the path the caller gave and what is wrong
  ("cannot write out/y.csv: folder out does not exist"), never the temporary name;
* :func:`check_writable` raises the same errors before any work, so a command can refuse a bad
  output path before a long computation;
* :func:`write_files_atomic` writes a set of files (a netlist and its companions) all or
  nothing as far as a file system allows;
* leftovers: a process killed with SIGKILL cannot remove its temporary file. The next write of
  the same file removes every ``.NAME.<pid>-<random>.tmp`` whose process is gone and which has
  not changed for an hour (the hour guards a writer this machine cannot see: another host on a
  network share, another PID namespace).

Replacing a file by rename gives it a new inode: other hard links to the old file keep the old
content.
"""

from __future__ import annotations

import errno
import io
import os
import re
import secrets
import stat
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO

# O_EXCL: the temporary name is ours alone; O_CLOEXEC: a subprocess started meanwhile does not
# inherit it; O_BINARY (Windows only): no newline translation below the text layer.
_CREATE = (
    os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
)
_TRIES = 100  # random temporary names tried before giving up (a clash is already unlikely)
_STALE_SECONDS = 3600.0  # a leftover temporary file untouched this long, its process gone


class WriteError(OSError):
    """An output file could not be written.

    ``filename`` is the path as the caller gave it, ``strerror`` says what is wrong in words
    and ``errno`` is the system's code; ``str()`` reads ``cannot write FILE: REASON``. The
    subclasses below are also the matching built-in ``OSError`` subclasses
    (``FileNotFoundError`` ...), so existing ``except`` clauses keep working.
    """

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


class MissingFolderError(WriteError, FileNotFoundError):
    """The folder the file should go in does not exist."""


class NotAFolderError(WriteError, NotADirectoryError):
    """A component of the path that should be a folder is a file."""


class IsAFolderError(WriteError, IsADirectoryError):
    """The path names a folder, not a file."""


class NoPermissionError(WriteError, PermissionError):
    """The folder (or the special file) does not let this user write."""


_CLASSES = {
    errno.ENOENT: MissingFolderError,
    errno.ENOTDIR: NotAFolderError,
    errno.EISDIR: IsAFolderError,
    errno.EACCES: NoPermissionError,
    errno.EPERM: NoPermissionError,
}


def _error(code: int, given: str, reason: str) -> WriteError:
    """The WriteError subclass matching ``code``, for the caller's path ``given``."""
    return _CLASSES.get(code, WriteError)(code, reason, given)


@dataclass(frozen=True)
class _Target:
    """Where the bytes for one path the caller gave really go."""

    given: str  # as the caller wrote it, for messages
    path: str  # the file replaced: ``given``, or a symbolic link's final target
    in_place: bool  # an existing special file (device, FIFO): written directly, not renamed
    mode: int | None  # permission bits of an existing regular file; None: a new file

    @property
    def folder(self) -> str:
        """The folder that receives the temporary file ("" for the current one)."""
        return os.path.dirname(self.path)


def _folder_words(folder: str) -> str:
    return f"folder {folder}" if folder else "the current folder"


def _resolve(path: str | os.PathLike) -> _Target:
    """Follow links and classify ``path``; raises WriteError if it can never be a file."""
    given = os.fspath(path)
    if isinstance(given, bytes):
        given = os.fsdecode(given)
    if not given:
        raise _error(errno.ENOENT, "''", "no file name given")
    try:
        info = os.stat(given)  # follows links: describes what open() would write to
    except FileNotFoundError:
        info = None  # a new file, or a link to a file still to be made
    except OSError as exc:  # a link loop, a file used as a folder, no search permission
        raise _explain(given, os.path.dirname(given), exc, "create") from exc
    if info is not None and stat.S_ISDIR(info.st_mode):
        raise _error(errno.EISDIR, given, "it is a directory")
    if info is not None and not stat.S_ISREG(info.st_mode):
        return _Target(given, given, True, None)
    trailing = given.endswith(("/", os.sep)) or os.path.basename(given) in (".", "..")
    if trailing:  # names a folder that does not exist (yet)
        raise _error(errno.EISDIR, given, "the name ends like a folder's, not a file's")
    target = given
    if os.path.islink(given):
        # realpath gives the final target even when that does not exist yet (a dangling link:
        # open() would create it, so do we); within a loop it stops on a link.
        target = os.path.realpath(given)
        if os.path.islink(target):
            raise _error(errno.ELOOP, given, "too many levels of symbolic links")
    mode = stat.S_IMODE(info.st_mode) if info is not None else None
    return _Target(given, target, False, mode)


def _explain(given: str, folder: str, exc: OSError, stage: str) -> WriteError:
    """Turn ``exc`` from creating (``stage="create"``) or renaming onto (``"replace"``) a file in
    ``folder`` into a WriteError that names ``given`` and says what is wrong."""
    code = exc.errno or errno.EIO
    if code in (errno.ENOENT, errno.ENOTDIR) and not os.path.isdir(folder or "."):
        # The deepest part of the folder that exists says which of the two it is.
        existing = folder
        while existing and not os.path.lexists(existing):
            parent = os.path.dirname(existing)
            if parent == existing:
                break
            existing = parent
        if existing and os.path.lexists(existing) and not os.path.isdir(existing):
            return _error(errno.ENOTDIR, given, f"{existing} is a file, not a folder")
        return _error(errno.ENOENT, given, f"{_folder_words(folder)} does not exist")
    if code in (errno.EACCES, errno.EPERM):
        action = "create a file in" if stage == "create" else "replace it in"
        return _error(code, given, f"permission denied (cannot {action} {_folder_words(folder)})")
    if code == errno.EISDIR:
        return _error(code, given, "it is a directory")
    if code == errno.ELOOP:
        return _error(code, given, "too many levels of symbolic links")
    words = exc.strerror or str(exc)
    return _error(code, given, words[:1].lower() + words[1:])


def _create_temporary(target: _Target) -> tuple[int, str]:
    """Open a new hidden file beside ``target``; returns (descriptor, name)."""
    base = os.path.basename(target.path)
    remove_leftovers(target.path)
    for _ in range(_TRIES):
        tmp = os.path.join(target.folder, f".{base}.{os.getpid()}-{secrets.token_hex(4)}.tmp")
        try:
            # Mode 0666: the kernel applies the umask (and a folder's default ACL), exactly as
            # for open(path, "w"); no need to read the process-wide umask.
            fd = os.open(tmp, _CREATE, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise _explain(target.given, target.folder, exc, "create") from exc
        if target.mode is not None:
            try:
                os.chmod(tmp, target.mode)  # the existing file's permissions, not the default
            except BaseException:
                os.close(fd)
                _remove(tmp)
                raise
        return fd, tmp
    raise _error(errno.EEXIST, target.given, f"no free temporary name in {target.folder or '.'}")


def remove_leftovers(path: str | os.PathLike, older_than: float = _STALE_SECONDS) -> list[str]:
    """Remove the temporary files killed writers of ``path`` left; return their names.

    Parameters
    ----------
    path : str or path-like
        The file whose ``.NAME.<pid>-<random>.tmp`` siblings are looked at.
    older_than : float
        Seconds since a leftover last changed before it may go (its process must be gone too).

    Returns
    -------
    list of str
        The names removed (none when the folder cannot be listed).
    """
    folder, base = os.path.split(os.fspath(path))
    pattern = re.compile(rf"\.{re.escape(base)}\.(\d+)-[0-9a-f]{{8}}\.tmp")
    removed = []
    try:
        entries = list(os.scandir(folder or "."))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is None or int(match[1]) == os.getpid() or _process_exists(int(match[1])):
            continue
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            if now - entry.stat(follow_symlinks=False).st_mtime < older_than:
                continue
            os.unlink(entry.path)
        except OSError:
            continue
        removed.append(entry.path)
    return removed


def _process_exists(pid: int) -> bool:
    if os.name != "posix":  # Windows' os.kill(pid, 0) would send CTRL_C: assume it lives
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):  # another user's process (EPERM), or no such pid here
        return True
    return True


def _remove(name: str) -> None:
    """Delete ``name`` if it is there (cleanup must not hide the error being handled)."""
    try:
        os.unlink(name)
    except OSError:
        pass


def _is_about_the_file(exc: OSError, tmp: str) -> bool:
    """Whether ``exc`` (raised while writing) concerns the temporary file itself."""
    return exc.filename is None or exc.filename == tmp


def _write_temporary(target: _Target, write: Callable[[IO], None], binary: bool) -> str:
    """Write a complete, flushed temporary file for ``target``; returns its name."""
    fd, tmp = _create_temporary(target)
    try:
        with os.fdopen(fd, "wb" if binary else "w") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())  # the data is on disk before the name points to it
    except BaseException as exc:
        _remove(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, WriteError):
            if _is_about_the_file(exc, tmp):  # e.g. no space left: name the user's file
                raise _explain(target.given, target.folder, exc, "create") from exc
        raise
    return tmp


def _write_in_place(target: _Target, write: Callable[[IO], None], binary: bool) -> None:
    """Write a special file (device, FIFO) directly: it cannot be replaced by a rename."""
    try:
        handle = open(target.path, "wb" if binary else "w")
    except OSError as exc:
        raise _explain(target.given, target.folder, exc, "create") from exc
    with handle:
        write(handle)


def _replace(tmp: str, target: _Target) -> None:
    """Rename ``tmp`` onto ``target``; on failure remove ``tmp`` and raise a WriteError."""
    try:
        os.replace(tmp, target.path)
    except OSError as exc:
        _remove(tmp)
        raise _explain(target.given, target.folder, exc, "replace") from exc


def check_writable(path: str | os.PathLike) -> None:
    """Raise the error :func:`write_atomic` would raise for ``path``, before any work is done.

    Checks that ``path`` is not a folder, that its folder exists and that a file can be created
    there (by creating and at once removing an empty hidden file: permission bits alone do not
    tell, e.g. for root or on a read-only file system). Nothing visible changes.

    Parameters
    ----------
    path : path-like
        The output file, as the user gave it.

    Raises
    ------
    WriteError
        An :class:`OSError` whose message names ``path`` and the problem: ``IsAFolderError``
        (also an ``IsADirectoryError``), ``MissingFolderError`` (``FileNotFoundError``),
        ``NotAFolderError`` (``NotADirectoryError``), ``NoPermissionError``
        (``PermissionError``), or WriteError itself for anything else (read-only file system
        ...).
    """
    target = _resolve(path)
    if target.in_place:
        if not os.access(target.path, os.W_OK):
            raise _error(errno.EACCES, target.given, "permission denied")
        return
    fd, tmp = _create_temporary(target)
    os.close(fd)
    _remove(tmp)


def write_atomic(
    path: str | os.PathLike, write: Callable[[IO], None], binary: bool = False
) -> None:
    """Create or replace ``path`` with what ``write(handle)`` writes, atomically.

    ``write`` gets a temporary file beside ``path`` (text, or bytes if ``binary``), which is
    renamed onto ``path`` once complete. If anything fails, the temporary file is removed and an
    existing ``path`` is untouched. A link is followed (the link stays); a new file gets the
    permissions ``open`` would give, an existing one keeps its own.

    Parameters
    ----------
    path : path-like
        The file to write.
    write : callable
        Called once with the open handle.
    binary : bool
        Open the handle in bytes mode.

    Raises
    ------
    WriteError
        The file cannot be written (see :func:`check_writable`); an ``OSError``.
    Exception
        Whatever ``write`` raises, unchanged (except an OSError about the file itself, such as
        a full disk, which becomes a WriteError naming ``path``).
    """
    target = _resolve(path)
    if target.in_place:
        _write_in_place(target, write, binary)
        return
    _replace(_write_temporary(target, write, binary), target)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically (see :func:`write_atomic`)."""
    write_atomic(path, lambda handle: handle.write(text))


def write_files_atomic(contents: Mapping[str | os.PathLike, str | bytes]) -> None:
    """Write several files all or nothing: either every file is written or none is changed.

    Every target is checked, then every content is written to a temporary file, and only when
    all of them are complete are they renamed onto their targets. Should a rename still fail
    (the file system changed meanwhile), the files already replaced are put back from hard
    links made just before, and files that did not exist are removed again; only on a file
    system without hard links can such a late failure leave a mix.

    Parameters
    ----------
    contents : mapping
        Path -> text (``str``) or bytes.

    Raises
    ------
    WriteError
        A file cannot be written; its message names that file (see :func:`check_writable`).
    ValueError
        Two paths name the same file.
    """
    targets = [(_resolve(path), data) for path, data in contents.items()]
    seen: dict[str, str] = {}
    for target, _ in targets:
        key = os.path.normcase(os.path.abspath(target.path))
        if key in seen:
            raise ValueError(f"{seen[key]} and {target.given} are the same file")
        seen[key] = target.given
    for target, _ in targets:
        check_writable(target.given)
    temporaries: list[str | None] = []
    try:
        for target, data in targets:
            if target.in_place:
                temporaries.append(None)  # written only once everything else is ready
            else:
                binary = isinstance(data, bytes)
                temporaries.append(_write_temporary(target, _writer(data), binary))
    except BaseException:
        for tmp in temporaries:
            if tmp is not None:
                _remove(tmp)
        raise
    _commit(targets, temporaries)


def _writer(data: str | bytes) -> Callable[[IO], None]:
    return lambda handle: handle.write(data)


def _commit(targets: list[tuple[_Target, str | bytes]], temporaries: list[str | None]) -> None:
    """Rename every temporary onto its target, undoing the renames done if one fails.

    Special files are written last: being written in place, they cannot be put back.
    """
    done: list[tuple[_Target, str | None]] = []  # (target renamed onto, link to its old content)
    try:
        for (target, _), tmp in zip(targets, temporaries, strict=True):
            if tmp is None:
                continue
            backup = _backup(target) if target.mode is not None else None
            try:
                os.replace(tmp, target.path)
            except OSError as exc:
                if backup is not None:
                    _remove(backup)
                raise _explain(target.given, target.folder, exc, "replace") from exc
            done.append((target, backup))
        for (target, data), tmp in zip(targets, temporaries, strict=True):
            if tmp is None:
                _write_in_place(target, _writer(data), isinstance(data, bytes))
    except BaseException:
        for tmp in temporaries:
            if tmp is not None:
                _remove(tmp)  # those not renamed yet; a renamed one is no longer there
        for target, backup in reversed(done):
            _restore(target, backup)
        raise
    for _, backup in done:
        if backup is not None:
            _remove(backup)


def _backup(target: _Target) -> str | None:
    """A hard link to ``target``'s current content, or None where links are not possible."""
    base = os.path.basename(target.path)
    for _ in range(_TRIES):
        name = os.path.join(target.folder, f".{base}.{secrets.token_hex(4)}.old")
        try:
            os.link(target.path, name)
        except FileExistsError:
            continue
        except OSError:
            return None
        return name
    return None


def _restore(target: _Target, backup: str | None) -> None:
    """Undo one rename of :func:`_commit` without raising (the first error is the one to see).

    With a backup the old content goes back; a file the batch created is removed; an old file
    without a backup (no hard links here) cannot be restored and keeps the new content.
    """
    try:
        if backup is not None:
            os.replace(backup, target.path)
        elif target.mode is None:
            os.unlink(target.path)
    except OSError:
        pass


def write_figure_atomic(figure, path: str | os.PathLike, **savefig: object) -> None:
    """Render a matplotlib ``figure`` in memory, then write it to ``path`` atomically.

    The format follows ``path``'s suffix (PNG, PDF, SVG ...) unless ``savefig`` names one;
    ``savefig`` options (``dpi``, ``bbox_inches`` ...) go to ``Figure.savefig``. A figure made
    as ``matplotlib.figure.Figure`` needs no pyplot: nothing here chooses a backend (a
    notebook's stays as it was) or keeps the figure alive.
    """
    path = Path(path)
    buffer = io.BytesIO()
    savefig.setdefault("format", path.suffix.lstrip(".").lower() or "png")
    figure.savefig(buffer, **savefig)
    write_atomic(path, lambda handle: handle.write(buffer.getvalue()), binary=True)
