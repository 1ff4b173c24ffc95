"""The one module that writes files: bytes, text, JSON, images, figures, and the temp files
of streaming writers (videos, MCAP recordings), every one atomically.

Every write goes to a temporary file in the target's own folder (``.NAME.<random>.tmp``,
created here), is flushed and ``fsync``-ed, and is renamed onto the target with
``os.replace``: a reader, or a crash, sees the old file or the new one, never half of one.
A failed write removes its temporary file and leaves the old file as it was.

Permissions, one rule: a file gets the mode a plain ``open(path, "w")`` would give a new
file, ``0o666`` less the process umask (0o644 under the usual umask 022). The kernel applies
the umask when the temporary file is created (``os.open(..., 0o666)``), so the umask is never
read or changed here; a replaced file's old mode is not kept.

Writers that open the file themselves (imageio's FFmpeg, an MCAP writer) take a path from
:func:`temp_path`, write it, and end with :func:`finish` (or :func:`discard` on failure).
Folders above the target are created as needed.
"""

from __future__ import annotations

import json
import os
import secrets
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

FILE_MODE = 0o666
"""Mode of a new file before the process umask is applied (what ``open()`` uses)."""


def temp_path(path: str | Path, suffix: str = "") -> Path:
    """Create an empty temporary file beside ``path`` and return its path.

    The name is ``.NAME.<random>.tmp`` plus ``suffix`` (writers that choose a format by
    extension, such as imageio, need e.g. ``".mp4"``); its mode is :data:`FILE_MODE` less the
    umask. End with :func:`finish` (put it in place) or :func:`discard`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp{suffix}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, FILE_MODE)
        except FileExistsError:  # another writer drew the same name: draw again
            continue
        os.close(fd)
        return tmp


def finish(tmp: str | Path, path: str | Path) -> Path:
    """Put a complete temporary file from :func:`temp_path` in place of ``path``: ``fsync``
    it, then ``os.replace``. On failure the temporary file is removed and ``path`` is left as
    it was. Returns ``path``."""
    tmp, path = Path(tmp), Path(path)
    try:
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        discard(tmp)
        raise
    return path


def discard(tmp: str | Path) -> None:
    """Remove an unfinished temporary file (nothing if it is gone)."""
    Path(tmp).unlink(missing_ok=True)


def move(src: str | Path, dst: str | Path) -> Path:
    """Rename a complete file written by this module onto ``dst`` (same file system) with
    ``os.replace``, keeping its mode; ``src`` stays if the rename fails (a set of files
    committed together, such as a checkpoint, is completed by moving it again)."""
    os.replace(src, dst)
    return Path(dst)


@contextmanager
def open_atomic(path: str | Path, suffix: str = "") -> Iterator[IO[bytes]]:
    """``with open_atomic(path) as f: f.write(...)``: a binary file that replaces ``path``
    when the block ends, or is removed if the block raises."""
    tmp = temp_path(path, suffix)
    try:
        with open(tmp, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        discard(tmp)
        raise


def write_with(path: str | Path, write: Callable[[IO[bytes]], object], suffix: str = "") -> Path:
    """Write ``path`` by calling ``write(f)`` on the open binary temporary file (a figure's
    ``savefig``, an image's ``save``). Returns ``path``."""
    with open_atomic(path, suffix) as f:
        write(f)
    return Path(path)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path``. Returns ``path``."""
    return write_with(path, lambda f: f.write(data))


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` as UTF-8. Returns ``path``."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | Path, data: Any, indent: int | None = 2) -> Path:
    """Write ``data`` as JSON, ``indent`` spaces, a final newline; NumPy numbers and arrays,
    paths and classes are converted (:func:`json_default`). Returns ``path``."""
    return write_text(path, json.dumps(data, indent=indent, default=json_default) + "\n")


def json_default(o: Any) -> Any:
    """``json.dumps``' ``default`` for the values run records carry: NumPy scalars and arrays,
    paths, classes (as ``module.QualName``).

    Raises:
        TypeError: any other type.
    """
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, type):
        return f"{o.__module__}.{o.__qualname__}"
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def save_figure(fig: Any, path: str | Path, **savefig: Any) -> Path:
    """Write a Matplotlib figure (``savefig`` keywords, e.g. ``format="png", dpi=110``).
    Returns ``path``."""
    return write_with(path, lambda f: fig.savefig(f, **savefig))


def save_image(image: Any, path: str | Path, format: str = "PNG", **params: Any) -> Path:
    """Write an image (an (H, W[, C]) uint8 array or a PIL image) with Pillow in ``format``
    (``params``: Pillow's, e.g. ``optimize=True``). Returns ``path``."""
    from PIL import Image

    picture = image if isinstance(image, Image.Image) else Image.fromarray(image)
    return write_with(path, lambda f: picture.save(f, format=format, **params))
