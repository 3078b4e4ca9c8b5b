"""Letting a child process write only beneath one folder: Linux's Landlock.

Landlock (Linux 5.13 and later; ``man 7 landlock``) lets an unprivileged process give up
rights for itself and every program it executes. :func:`write_confinement` builds, in the
parent, a Landlock ruleset that handles every right to change the file system (write and
truncate files; make, remove and rename entries) and grants them beneath one folder only,
and with ABI 4 or later also handles TCP bind and connect and grants none; it returns the
function that the child runs between ``fork`` and ``exec`` (``preexec_fn``): set
``no_new_privs`` and restrict itself. Reading stays allowed everywhere (ngspice reads its
``spinit`` and code models from the system folders). Where the kernel has no Landlock
(another OS, an older kernel, a container that blocks the system calls) it returns None and
the caller runs the program without it.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
from collections.abc import Callable
from pathlib import Path

__all__ = ["landlock_abi", "write_confinement"]

# system call numbers, the same on every Linux architecture (asm-generic and x86 tables)
_CREATE_RULESET, _ADD_RULE, _RESTRICT_SELF = 444, 445, 446
_CREATE_RULESET_VERSION = 1
_RULE_PATH_BENEATH = 1
_PR_SET_NO_NEW_PRIVS = 38

# LANDLOCK_ACCESS_FS_* (linux/landlock.h): every right that changes the file system
_WRITE_FILE, _REMOVE_DIR, _REMOVE_FILE = 1 << 1, 1 << 4, 1 << 5
_MAKE = sum(1 << bit for bit in range(6, 13))  # MAKE_CHAR DIR REG SOCK FIFO BLOCK SYM
_REFER, _TRUNCATE = 1 << 13, 1 << 14  # ABI 2, ABI 3
_NET_TCP = (1 << 0) | (1 << 1)  # LANDLOCK_ACCESS_NET_BIND_TCP, CONNECT_TCP (ABI 4)


class _RulesetAttr(ctypes.Structure):
    _fields_ = [("handled_access_fs", ctypes.c_uint64), ("handled_access_net", ctypes.c_uint64)]


class _PathBeneathAttr(ctypes.Structure):
    _pack_ = 1
    _fields_ = [("allowed_access", ctypes.c_uint64), ("parent_fd", ctypes.c_int32)]


@functools.cache
def _libc() -> ctypes.CDLL | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(None, use_errno=True)
    except OSError:  # pragma: no cover - no C library to call
        return None


@functools.cache
def landlock_abi() -> int:
    """The kernel's Landlock ABI version (0: no Landlock here)."""
    libc = _libc()
    if libc is None:
        return 0
    version = libc.syscall(_CREATE_RULESET, None, ctypes.c_size_t(0), _CREATE_RULESET_VERSION)
    return max(int(version), 0)


def write_confinement(
    folder: Path, also_write: tuple[Path, ...] = ()
) -> tuple[Callable[[], None], int] | None:
    """A ``preexec_fn`` that lets the child write beneath ``folder`` only, and its ruleset.

    Parameters
    ----------
    folder : Path
        The one folder the child (and what it executes) may change anything in.
    also_write : tuple of Path
        Folders beneath which the child may write to (and truncate) files that exist or that
        it opens unnamed (``O_TMPFILE``), but not make, remove or rename any entry.

    Returns
    -------
    (callable, int) or None
        The function for ``subprocess.Popen(preexec_fn=...)`` and the ruleset's file
        descriptor (pass it in ``pass_fds`` and close it in the parent once the child has
        started); None where the kernel has no Landlock.

    Raises
    ------
    OSError
        The kernel has Landlock but refused the ruleset or the folder's rule.
    """
    abi = landlock_abi()
    libc = _libc()
    if abi < 1 or libc is None:
        return None
    handled = _WRITE_FILE | _REMOVE_DIR | _REMOVE_FILE | _MAKE
    handled |= (_REFER if abi >= 2 else 0) | (_TRUNCATE if abi >= 3 else 0)
    attr = _RulesetAttr(handled, _NET_TCP if abi >= 4 else 0)
    size = ctypes.sizeof(attr) if abi >= 4 else ctypes.sizeof(ctypes.c_uint64)
    ruleset = libc.syscall(_CREATE_RULESET, ctypes.byref(attr), ctypes.c_size_t(size), 0)
    if ruleset < 0:
        raise _errno("landlock_create_ruleset")
    file_rights = _WRITE_FILE | (_TRUNCATE if abi >= 3 else 0)
    try:
        _add_rule(libc, ruleset, folder, handled)
        for other in also_write:
            _add_rule(libc, ruleset, other, file_rights)
    except BaseException:
        os.close(ruleset)
        raise
    prctl, syscall = libc.prctl, libc.syscall  # looked up here: the child only calls

    def restrict() -> None:  # runs in the child, between fork and exec
        if prctl(_PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0 or syscall(_RESTRICT_SELF, ruleset, 0):
            raise OSError(ctypes.get_errno(), "landlock_restrict_self failed")
        os.close(ruleset)

    return restrict, ruleset


def _add_rule(libc: ctypes.CDLL, ruleset: int, folder: Path, rights: int) -> None:
    """Grant ``rights`` beneath ``folder`` in ``ruleset``."""
    where = os.open(folder, os.O_PATH | os.O_CLOEXEC | os.O_DIRECTORY)
    try:
        rule = _PathBeneathAttr(rights, where)
        if libc.syscall(_ADD_RULE, ruleset, _RULE_PATH_BENEATH, ctypes.byref(rule), 0) < 0:
            raise _errno(f"landlock_add_rule on {folder}")
    finally:
        os.close(where)


def _errno(call: str) -> OSError:
    number = ctypes.get_errno()
    return OSError(number, f"{call}: {os.strerror(number)}")
