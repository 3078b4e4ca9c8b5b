"""Writing files without ever leaving a half-written one: temporary name, then rename.

A leaf module (imports nothing of ours), usable from every room and the CLI.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO


def write_atomic(
    path: str | os.PathLike, write: Callable[[IO], None], binary: bool = False
) -> None:
    """Create ``path`` by calling ``write(handle)`` on a temporary file beside it, then renaming.

    If ``write`` raises, the temporary file is removed and an existing ``path`` is untouched.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb" if binary else "w") as handle:
            write(handle)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    write_atomic(path, lambda handle: handle.write(text))


def write_figure_atomic(figure, path: str | os.PathLike, **savefig: object) -> None:
    """Render a matplotlib ``figure`` in memory, then write it to ``path`` atomically.

    The format follows ``path``'s suffix (PNG, PDF, SVG ...) unless ``savefig`` names one;
    ``savefig`` options (``dpi``, ``bbox_inches`` ...) go to ``Figure.savefig``. A figure made
    as ``matplotlib.figure.Figure`` needs no pyplot: nothing here chooses a backend (a
    notebook's stays as it was) or keeps the figure alive.
    """
    import io

    path = Path(path)
    buffer = io.BytesIO()
    savefig.setdefault("format", path.suffix.lstrip(".").lower() or "png")
    figure.savefig(buffer, **savefig)
    write_atomic(path, lambda handle: handle.write(buffer.getvalue()), binary=True)
