"""Text files in and out: decoding with a clear error, and all-or-nothing atomic writes."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from .._errors import InputError


def read_text(path) -> tuple[str, str]:
    """The file's text (UTF-8, a BOM allowed) and the SHA-256 of its bytes; a missing or unreadable
    file is an InputError."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise InputError("file not found", source=str(path)) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror}", source=str(path)) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(f"not UTF-8 text ({e.reason} at byte {e.start})", source=str(path)) from None
    return text, hashlib.sha256(raw).hexdigest()


def write_texts(files: dict, *, force: bool = False) -> None:
    """Write several text files all-or-nothing: refuse if any exists (unless ``force``), write
    each to a temporary name in its own directory, and rename only once every write succeeded.

    The rename is atomic per file (``os.replace``), so a reader never sees half a file.
    """
    paths = [Path(p) for p in files]
    if not force:
        for p in paths:
            if p.exists():
                raise InputError("exists; pass force=True (--force) to overwrite", source=str(p))
    staged = []
    try:
        for p, text in zip(paths, files.values()):
            tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
            staged.append((tmp, p))
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                fh.write(text)
        for tmp, p in staged:
            os.replace(tmp, p)
    finally:
        for tmp, _ in staged:
            if tmp.exists():
                tmp.unlink()
