"""Text files in and out: bounded reading with a clear error, YAML and JSON parsed safely, and
all-or-nothing atomic writes that never follow a link.

The limits below are stated in docs/formats.md. Every error names the user's file and the line.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import tempfile
from pathlib import Path

import yaml

from .._errors import InputError, excerpt

# a file larger than this is refused before it is read (the largest sensible campaign is ~100 MB)
MAX_FILE_BYTES = 256 * 2 ** 20
# nesting of YAML/JSON collections: model and result files need 6; the rest is a bomb or a mistake
MAX_DEPTH = 32
# one text value (a name, a description): longer is a pasted file, not a value
MAX_SCALAR = 100_000
# digits of an integer in a YAML/JSON file: more cannot be a robocal value and cannot become a float
MAX_DIGITS = 30


def read_bytes(path, *, limit: int = MAX_FILE_BYTES) -> bytes:
    """The file's bytes; a missing, unreadable or oversized file is an InputError."""
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > limit:
                raise InputError(f"the file is {size / 2 ** 20:.0f} MB; robocal reads files up to "
                                 f"{limit / 2 ** 20:.0f} MB", source=str(path))
            raw = fh.read(limit + 1)
    except FileNotFoundError:
        raise InputError("cannot read: file not found", source=str(path)) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a file", source=str(path)) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror}", source=str(path)) from None
    if len(raw) > limit:
        raise InputError(f"the file exceeds {limit / 2 ** 20:.0f} MB", source=str(path))
    return raw


def decode(raw: bytes, source: str) -> str:
    """UTF-8 text (a BOM allowed); any other encoding is an InputError naming the line."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise InputError(f"not UTF-8 text ({e.reason} at byte {e.start}); save the file as UTF-8", source=source,
                         where=f"line {line}") from None
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise InputError("a NUL character: this is a binary file, not text", source=source, where=f"line {line}")
    return text


def read_text(path) -> tuple[str, str]:
    """The file's text (UTF-8, a BOM allowed) and the SHA-256 of its bytes; a missing, unreadable,
    oversized or non-UTF-8 file is an InputError."""
    raw = read_bytes(path)
    return decode(raw, str(path)), hashlib.sha256(raw).hexdigest()


# -- YAML without aliases, deep nesting or duplicate keys -----------------------------------------

def _line(node) -> int:
    return node.start_mark.line + 1


class _SafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing what a model file never needs: aliases (``*name``, the
    expansion bombs), nesting beyond MAX_DEPTH, duplicate keys, huge integers and huge scalars."""

    def __init__(self, text, source):
        super().__init__(text)
        self.source, self.depth = source, 0

    def error(self, node_or_mark, message):
        mark = getattr(node_or_mark, "start_mark", node_or_mark)
        return InputError(message, source=self.source, where=f"line {mark.line + 1}, column {mark.column + 1}")

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise self.error(event.start_mark, f"alias *{excerpt(event.anchor)[1:-1]}: aliases are not allowed "
                                               "in robocal files; write the value out")
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(self.peek_event().start_mark, f"nested more than {MAX_DEPTH} levels deep")
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                key = key_node.value
                if key in seen:
                    raise self.error(key_node, f"key {excerpt(key)} given twice (lines {seen[key]} and "
                                               f"{_line(key_node)})")
                seen[key] = _line(key_node)
        return super().construct_mapping(node, deep=deep)

    def construct_scalar(self, node):
        if isinstance(node.value, str) and len(node.value) > MAX_SCALAR:
            raise self.error(node, f"a value of {len(node.value)} characters; robocal reads up to {MAX_SCALAR}")
        return super().construct_scalar(node)

    def construct_yaml_int(self, node):
        if len(re.sub(r"[^0-9a-fA-F]", "", node.value)) > MAX_DIGITS:
            raise self.error(node, f"number {excerpt(node.value)} too large")
        return super().construct_yaml_int(node)


_SafeLoader.add_constructor("tag:yaml.org,2002:int", _SafeLoader.construct_yaml_int)


def load_yaml(text: str, source: str):
    """The YAML document in ``text``, parsed safely (see _SafeLoader); InputError naming the line."""
    loader = _SafeLoader(text, source)
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        raise InputError(f"not valid YAML: {e.problem or e.context}", source=source, where=where) from None
    except yaml.YAMLError as e:
        raise InputError(f"not valid YAML: {excerpt(str(e))}", source=source) from None
    finally:
        loader.dispose()


# -- JSON without duplicate keys, NaN, huge numbers or deep nesting ----------------------------

def _key_lines(text: str, key: str) -> str:
    pattern = re.compile(re.escape(json.dumps(key)) + r"\s*:")
    lines = [text[:m.start()].count("\n") + 1 for m in pattern.finditer(text)][:2]
    return f" (lines {lines[0]} and {lines[1]})" if len(lines) == 2 else ""


def load_json(text: str, source: str):
    """The JSON document in ``text``; duplicate keys, NaN/Infinity, integers beyond MAX_DIGITS
    digits, numbers beyond the float range and nesting beyond MAX_DEPTH are InputErrors."""
    def pairs(items):
        d = {}
        for k, v in items:
            if k in d:
                raise InputError(f"key {excerpt(k)} given twice{_key_lines(text, k)}", source=source)
            d[k] = v
        return d

    def integer(s):
        if len(s.lstrip("-")) > MAX_DIGITS:
            raise InputError(f"number {excerpt(s)} too large", source=source)
        return int(s)

    def number(s):
        v = float(s)
        if v in (float("inf"), float("-inf")):
            raise InputError(f"number {excerpt(s)} beyond the range of floating point", source=source)
        return v

    def constant(s):
        raise InputError(f"{s} is not JSON (a missing value is null)", source=source)

    try:
        d = json.loads(text, object_pairs_hook=pairs, parse_int=integer, parse_float=number, parse_constant=constant)
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON: {e.msg}", source=source, where=f"line {e.lineno}, column {e.colno}") from None
    except RecursionError:
        d = None
    if d is None or _depth(d) > MAX_DEPTH:
        raise InputError(f"nested more than {MAX_DEPTH} levels deep" if d is not None else "nested too deeply",
                         source=source)
    return d


def _depth(obj) -> int:
    """Nesting depth of lists and dicts, without recursion."""
    deepest, stack = 0, [(obj, 1)]
    while stack:
        o, k = stack.pop()
        if isinstance(o, (list, dict)):
            deepest = max(deepest, k)
            stack.extend((v, k + 1) for v in (o.values() if isinstance(o, dict) else o))
    return deepest


# -- writing ------------------------------------------------------------------------------------

class Interrupted(KeyboardInterrupt):
    """SIGTERM, raised as an exception so that temporary files are removed on the way out."""


def _terminate(signum, frame):
    raise Interrupted(f"terminated by signal {signum}")


def check_writable(paths, *, force: bool = False) -> None:
    """Before any work: each output can be written (its folder exists or can be made and is
    writable, the path is not a folder) and, unless ``force``, does not exist yet."""
    for p in map(Path, paths):
        if p.is_dir():
            raise InputError("is a folder; give a file name", source=str(p))
        if not force and (p.exists() or p.is_symlink()):
            raise InputError("exists; pass --force to overwrite", source=str(p))
        folder = p.parent
        while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
            folder = folder.parent
        if not folder.is_dir():
            raise InputError(f"cannot write here: {folder} is a file, not a folder", source=str(p))
        try:  # a probe, not os.access: that says yes to root on a read-only disk
            fd, probe = tempfile.mkstemp(prefix=".robocal-probe.", dir=folder)
            os.close(fd)
            os.unlink(probe)
        except OSError as e:
            raise InputError(f"cannot write in the folder {folder}: {e.strerror}", source=str(p)) from None


def write_texts(files: dict, *, force: bool = False) -> None:
    """Write several text files all-or-nothing: refuse if any exists (unless ``force``), write
    each to a fresh temporary file in its own folder (created exclusively under an unpredictable
    name, so a link planted there is never followed), and rename only once every write succeeded.

    The rename is atomic per file (``os.replace``; a link at the final name is replaced, not
    followed), so a reader never sees half a file. Temporary files are removed on every path the
    process controls: errors, Ctrl-C and SIGTERM. Errors name the user's path.
    """
    paths = [Path(p) for p in files]
    if not force:
        for p in paths:
            if p.exists() or p.is_symlink():
                raise InputError("exists; pass force=True (--force) to overwrite", source=str(p))
    staged = []
    previous = _on_sigterm(_terminate)
    try:
        for p, text in zip(paths, files.values()):
            try:
                fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror}", source=str(p)) from None
            staged.append((tmp, p))
            try:
                with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
                    fh.write(text)
                    fh.flush()
                    os.fsync(fh.fileno())
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror}", source=str(p)) from None
        for tmp, p in staged:
            try:
                os.replace(tmp, p)
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror}", source=str(p)) from None
    finally:
        for tmp, _ in staged:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        _on_sigterm(previous)


def _on_sigterm(handler):
    """Install ``handler`` for SIGTERM (main thread only); the previous one, or None."""
    if handler is None:
        return None
    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        return None
