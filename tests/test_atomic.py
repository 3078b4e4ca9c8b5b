"""Atomic writes behave like an ordinary ``open(path, "w")`` from the outside: the permissions
a new file gets, an existing file's permissions, links followed, special files written in place,
errors naming the user's path - and, unlike ``open``, never a half-written or mixed result."""

import errno
import os
import stat
import threading
from contextlib import contextmanager

import pytest

from circuitsim.atomic import (
    WriteError,
    check_writable,
    write_atomic,
    write_files_atomic,
    write_text_atomic,
)


@contextmanager
def umask(mask: int):
    """Run the body under ``mask``, restoring the previous umask however it ends."""
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def names(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# --- permissions --------------------------------------------------------------------------


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077, 0o027], ids=oct)
def test_a_new_file_gets_the_permissions_open_would_give(tmp_path, mask):
    with umask(mask):
        write_text_atomic(tmp_path / "new.csv", "x\n")
        with open(tmp_path / "plain.csv", "w") as handle:  # the reference: an ordinary open
            handle.write("x\n")
    assert mode(tmp_path / "new.csv") == 0o666 & ~mask == mode(tmp_path / "plain.csv")


def test_an_existing_file_keeps_its_permissions(tmp_path):
    path = tmp_path / "keep.csv"
    path.write_text("old\n")
    os.chmod(path, 0o664)  # wider than the umask below allows a new file
    with umask(0o077):
        write_text_atomic(path, "new\n")
    assert path.read_text() == "new\n"
    assert mode(path) == 0o664
    os.chmod(path, 0o640)
    with umask(0o022):
        write_atomic(path, lambda handle: handle.write(b"bytes"), binary=True)
    assert path.read_bytes() == b"bytes"
    assert mode(path) == 0o640


# --- symbolic links and special files -----------------------------------------------------


def test_a_link_is_followed_and_stays_a_link(tmp_path):
    target = tmp_path / "keep.csv"
    target.write_text("old\n")
    os.chmod(target, 0o644)
    link = tmp_path / "link.csv"
    link.symlink_to("keep.csv")
    with umask(0o077):
        write_text_atomic(link, "new\n")
    assert link.is_symlink() and os.readlink(link) == "keep.csv"
    assert target.read_text() == "new\n"
    assert mode(target) == 0o644
    assert names(tmp_path) == ["keep.csv", "link.csv"]  # no temporary file left


def test_a_link_through_another_folder_writes_there(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "out").mkdir()
    link = tmp_path / "out" / "w.csv"
    link.symlink_to(tmp_path / "real" / "w.csv")  # dangling: open() would create the target
    write_text_atomic(link, "data\n")
    assert link.is_symlink()
    assert (tmp_path / "real" / "w.csv").read_text() == "data\n"
    assert names(tmp_path / "out") == ["w.csv"] and names(tmp_path / "real") == ["w.csv"]


def test_a_link_loop_is_refused(tmp_path):
    (tmp_path / "a").symlink_to("b")
    (tmp_path / "b").symlink_to("a")
    with pytest.raises(OSError, match="symbolic links") as caught:
        write_text_atomic(tmp_path / "a", "x")
    assert str(tmp_path / "a") in str(caught.value)
    assert (tmp_path / "a").is_symlink() and (tmp_path / "b").is_symlink()


def test_a_fifo_is_written_in_place_not_replaced(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received = []

    def read() -> None:
        with open(fifo) as handle:  # blocks until a writer opens the FIFO
            received.append(handle.read())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    write_text_atomic(fifo, "through the pipe\n")
    reader.join(timeout=10)
    assert received == ["through the pipe\n"]
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert names(tmp_path) == ["pipe"]


# --- errors name the user's path and say what is wrong -------------------------------------


def test_a_missing_folder(tmp_path):
    path = tmp_path / "nope" / "y.csv"
    with pytest.raises(FileNotFoundError) as caught:
        write_text_atomic(path, "x")
    assert str(caught.value) == f"cannot write {path}: folder {tmp_path / 'nope'} does not exist"
    assert caught.value.filename == str(path) and caught.value.errno == errno.ENOENT
    assert isinstance(caught.value, WriteError)
    assert names(tmp_path) == []


def test_a_file_where_a_folder_should_be(tmp_path):
    (tmp_path / "f").write_text("keep")
    path = tmp_path / "f" / "sub" / "y.csv"
    with pytest.raises(NotADirectoryError) as caught:
        write_text_atomic(path, "x")
    assert str(caught.value) == f"cannot write {path}: {tmp_path / 'f'} is a file, not a folder"
    assert (tmp_path / "f").read_text() == "keep"


def test_a_directory_is_not_replaced(tmp_path, monkeypatch):
    (tmp_path / "adir").mkdir()
    (tmp_path / "adir" / "inside").write_text("keep")
    monkeypatch.chdir(tmp_path)
    for given in ("adir", "adir/", str(tmp_path / "adir"), ".", "./", ".."):
        with pytest.raises(IsADirectoryError) as caught:
            write_text_atomic(given, "x")
        assert str(caught.value) == f"cannot write {given}: it is a directory"
    assert names(tmp_path) == ["adir"] and names(tmp_path / "adir") == ["inside"]


def test_the_root_folder_is_a_directory():
    with pytest.raises(IsADirectoryError, match="cannot write /: it is a directory"):
        check_writable("/")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_folder_without_write_permission(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    os.chmod(locked, 0o555)
    try:
        with pytest.raises(PermissionError) as caught:
            write_text_atomic(locked / "y.csv", "x")
        with pytest.raises(PermissionError):
            check_writable(locked / "y.csv")
    finally:
        os.chmod(locked, 0o755)
    assert str(caught.value).startswith(f"cannot write {locked / 'y.csv'}: permission denied")
    assert names(locked) == []


def test_permission_denied_by_the_system_is_named(tmp_path, monkeypatch):
    # Whatever refuses (mode bits, a read-only mount, sysfs even for root), the error the
    # system gives on creating the file is reported against the user's path.
    real_open = os.open

    def refusing_open(name, flags, *args, **kwargs):
        if str(name).startswith(str(tmp_path)) and flags & os.O_CREAT:
            raise PermissionError(errno.EACCES, "Permission denied", name)
        return real_open(name, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", refusing_open)
    path = tmp_path / "y.csv"
    for attempt in (lambda: write_text_atomic(path, "x"), lambda: check_writable(path)):
        with pytest.raises(PermissionError) as caught:
            attempt()
        assert str(caught.value) == (
            f"cannot write {path}: permission denied (cannot create a file in folder {tmp_path})"
        )
        assert ".tmp" not in str(caught.value)


def test_a_full_disk_names_the_file_not_the_temporary(tmp_path):
    path = tmp_path / "y.csv"
    path.write_text("old\n")

    def fill(handle):
        handle.write("partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError) as caught:
        write_atomic(path, fill)
    assert str(caught.value) == f"cannot write {path}: no space left on device"
    assert caught.value.errno == errno.ENOSPC
    assert path.read_text() == "old\n" and names(tmp_path) == ["y.csv"]


def test_other_errors_of_the_writer_pass_unchanged(tmp_path):
    path = tmp_path / "y.csv"
    path.write_text("old\n")

    def fail(handle):
        raise ValueError("bad data")

    with pytest.raises(ValueError, match="^bad data$"):
        write_atomic(path, fail)
    assert path.read_text() == "old\n" and names(tmp_path) == ["y.csv"]


# --- early checks -------------------------------------------------------------------------


def test_check_writable_accepts_good_paths_and_leaves_nothing(tmp_path):
    check_writable(tmp_path / "new.csv")
    (tmp_path / "old.csv").write_text("keep")
    check_writable(tmp_path / "old.csv")
    (tmp_path / "link.csv").symlink_to("old.csv")
    check_writable(tmp_path / "link.csv")
    assert names(tmp_path) == ["link.csv", "old.csv"]
    assert (tmp_path / "old.csv").read_text() == "keep"


def test_check_writable_raises_what_the_write_would(tmp_path):
    (tmp_path / "adir").mkdir()
    for path, kind in [
        (tmp_path / "nope" / "y.csv", FileNotFoundError),
        (tmp_path / "adir", IsADirectoryError),
    ]:
        with pytest.raises(kind) as early:
            check_writable(path)
        with pytest.raises(kind) as late:
            write_text_atomic(path, "x")
        assert str(early.value) == str(late.value)
        assert str(early.value).startswith(f"cannot write {path}: ")


# --- several files, all or nothing ---------------------------------------------------------


def test_write_files_atomic_writes_all(tmp_path):
    with umask(0o022):
        write_files_atomic({tmp_path / "a.txt": "text\n", tmp_path / "b.bin": b"\x00\x01"})
    assert (tmp_path / "a.txt").read_text() == "text\n"
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert mode(tmp_path / "a.txt") == 0o644
    assert names(tmp_path) == ["a.txt", "b.bin"]


def test_write_files_atomic_changes_nothing_if_one_target_is_bad(tmp_path):
    (tmp_path / "a.txt").write_text("old a\n")
    (tmp_path / "c.txt").mkdir()
    with pytest.raises(IsADirectoryError, match=r"c\.txt: it is a directory"):
        write_files_atomic(
            {tmp_path / "a.txt": "new a\n", tmp_path / "b.txt": "new b\n", tmp_path / "c.txt": "c"}
        )
    assert (tmp_path / "a.txt").read_text() == "old a\n"
    assert names(tmp_path) == ["a.txt", "c.txt"]


def test_write_files_atomic_undoes_renames_when_a_late_one_fails(tmp_path, monkeypatch):
    # The file system changes between the checks and the renames: the last rename fails.
    (tmp_path / "a.txt").write_text("old a\n")
    os.chmod(tmp_path / "a.txt", 0o640)
    (tmp_path / "c.txt").write_text("old c\n")
    real_replace = os.replace

    def replace(src, dst):
        if os.fspath(dst).endswith("c.txt"):
            raise OSError(errno.EIO, "Input/output error", src, dst)
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError) as caught:
        write_files_atomic(
            {tmp_path / "a.txt": "new a\n", tmp_path / "b.txt": "new b\n", tmp_path / "c.txt": "c"}
        )
    assert str(caught.value) == f"cannot write {tmp_path / 'c.txt'}: input/output error"
    assert (tmp_path / "a.txt").read_text() == "old a\n" and mode(tmp_path / "a.txt") == 0o640
    assert (tmp_path / "c.txt").read_text() == "old c\n"
    assert names(tmp_path) == ["a.txt", "c.txt"]  # b.txt removed again, no temporaries


def test_write_files_atomic_refuses_one_file_twice(tmp_path):
    (tmp_path / "link.txt").symlink_to("a.txt")
    with pytest.raises(ValueError, match="same file"):
        write_files_atomic({tmp_path / "a.txt": "1", tmp_path / "link.txt": "2"})
    assert names(tmp_path) == ["link.txt"]
