"""The user cache directory of circuitsim: numba's machine code, the start-up library, the
compile timings (a leaf module: the kernels' decorator reads it before numba is imported)."""

from __future__ import annotations

import os
from pathlib import Path

CACHE_ENV = "CIRCUITSIM_CACHE_DIR"


def cache_root() -> Path:
    """The user cache directory of circuitsim (not created here)."""
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg and os.path.isabs(xdg):
        return Path(xdg) / "circuitsim"
    try:
        return Path.home() / ".cache" / "circuitsim"
    except RuntimeError:  # no home directory to be found (a bare service account)
        import tempfile

        return Path(tempfile.gettempdir()) / "circuitsim-cache"
