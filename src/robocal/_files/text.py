"""Text files in and out: bounded reading with a clear error, YAML and JSON parsed safely, and
all-or-nothing atomic writes that never follow a link.

The limits below are stated in docs/formats.md. Every error names the user's file and the line.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import os
import re
import secrets
import select
import stat
from pathlib import Path
from typing import NamedTuple

import yaml

from .._base.arguments import PATH, accepts
from .._base.errors import InputError, excerpt
from .._base.options import MAX_HEADER_LINES

# a file larger than this is refused before it is read (the largest sensible campaign is ~100 MB)
MAX_FILE_BYTES = 256 * 2 ** 20
# one line of a table (measurement, repeatability, contact file): a header of 100,000 columns
MAX_LINE_BYTES = 2 ** 20
# nesting of YAML/JSON collections: model and result files need 6; the rest is a bomb or a mistake
MAX_DEPTH = 32
# bytes read at a time where a file's size is not known in advance
READ_CHUNK = 16 * 2 ** 20
# a FIFO that no program has opened for writing yet: how long to wait for one before refusing it
FIFO_WAIT_SECONDS = 2.0
# one text value (a name, a description): longer is a pasted file, not a value
MAX_SCALAR = 100_000
# digits of an integer in a YAML/JSON file: more cannot be a robocal value and cannot become a float
MAX_DIGITS = 30


def read_bytes(path, *, limit: int = MAX_FILE_BYTES, text: bool = True, lines: int | None = None,
               rows: tuple[int, str, int | None] | None = None, regular: bool = False) -> bytes:
    """The file's bytes, opened once and read once within a budget; a missing, unreadable or
    oversized file is an InputError naming it.

    The budget: ``limit`` bytes; ``lines`` lines when given; and for a table of ``rows`` = (most,
    what, per_gb), at most ``most`` data rows (and ``per_gb`` per GB of memory available, when
    given) besides MAX_HEADER_LINES other lines (``check_rows``). A regular file is refused by its
    size before anything is read; its lines, and a stream's (a FIFO, a pipe such as ``<(command)``,
    a device), are counted a chunk at a time as they are read, which stops as soon as the budget
    runs out or, for ``text``, at a NUL character (``/dev/zero``, ``/dev/urandom``). A FIFO that no
    program writes into is refused after FIFO_WAIT_SECONDS. With ``regular``, anything but a regular
    file is refused before it is read (a file only robocal writes, whose budget is no stream's).
    """
    source = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputError("cannot read: file not found", source=source) from None
    except ValueError:  # a NUL in the name
        raise InputError("not a valid file name", source=excerpt(source)) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror}", source=source) from None
    budget = _Budget.of(limit, lines, rows)
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise InputError("is a folder, not a file", source=source)
        if regular and not stat.S_ISREG(st.st_mode):
            kind = next((said for test, said in _KINDS if test(st.st_mode)), "something other than a file")
            raise InputError(f"is {kind}, not the file robocal wrote", source=source)
        if stat.S_ISREG(st.st_mode) and st.st_size > limit:
            raise InputError(f"the file is {st.st_size / 2 ** 20:.0f} MB; robocal reads files up to "
                             f"{limit / 2 ** 20:.0f} MB", source=source)
        first = _first_of_fifo(fd, source) if stat.S_ISFIFO(st.st_mode) else b""
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", buffering=0) as fh:
            fd = -1  # closed with fh
            raw, newlines = budget.read(fh, first, source, text, st.st_size if stat.S_ISREG(st.st_mode) else 0)
    except InputError:  # too large (an InputError is a ValueError too)
        raise
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror}", source=source) from None
    finally:
        if fd >= 0:
            os.close(fd)
    if rows is not None:
        check_rows(raw, source, *rows, newlines=newlines)
    return raw


def _first_of_fifo(fd: int, source: str) -> bytes:
    """What a FIFO holds already (b"" when a writer has written nothing yet); refused when no program
    opens it for writing within FIFO_WAIT_SECONDS."""
    try:
        first = os.read(fd, READ_CHUNK)
    except BlockingIOError:  # a writer is there, nothing written yet: its stream is read as it comes
        return b""
    if first:
        return first
    poll = select.poll()  # no writer yet (or one that wrote nothing and left: the poll says so at once)
    poll.register(fd, select.POLLIN)
    if not poll.poll(FIFO_WAIT_SECONDS * 1000):
        raise InputError(f"a FIFO that no program writes into (nothing came in {FIFO_WAIT_SECONDS:g} s); start "
                         "the program that writes it first, or give a file", source=source)
    return b""


class _Budget(NamedTuple):
    """What a read may take: ``limit`` bytes and ``lines`` line ends (None: any number), and the
    words of the refusal when the lines run out."""

    limit: int
    lines: int | None
    said: str

    @classmethod
    def of(cls, limit: int, lines: int | None, rows: tuple[int, str, int | None] | None) -> _Budget:
        if rows is None:
            return cls(limit, lines, f"{lines or 0:,} from this kind of file (docs/formats.md)")
        most, what, per_gb = rows
        bound, memory = _row_bound(most, per_gb)
        room = f"with {memory / 2 ** 30:.1f} GB of memory available " if memory is not None and bound < most else ""
        said = f"{room}{bound:,} {what} and {MAX_HEADER_LINES:,} other lines per file (docs/formats.md)"
        return cls(limit, bound + MAX_HEADER_LINES if lines is None else min(lines, bound + MAX_HEADER_LINES),
                   said)

    def read(self, fh, first: bytes, source: str, text: bool, size: int) -> tuple[bytes, int]:
        """(``first`` and the rest of ``fh``, their line ends), read a chunk at a time (a regular
        file of ``size`` bytes in one read) and refused as soon as they run over the budget or
        (``text``) hold a NUL character."""
        if self.lines is not None and size > 64 * (self.lines + 1):
            size = 0  # a file that may hold more lines than the budget: a chunk at a time, to stop early
        out = io.BytesIO()  # a stream's parts, grown in place: its value is handed out without a copy
        last = b""  # the latest part, kept apart: a file read in one part is handed out as it is
        total = newlines = 0
        part = first
        while True:
            if part:
                if text and b"\x00" in part:
                    line = newlines + part[:part.index(b"\x00")].count(b"\n") + 1
                    raise binary_error(part if not total else b"", source, line)
                newlines += part.count(b"\n")
                out.write(last)
                last = part
                total += len(part)
                if total > self.limit:
                    raise InputError(f"the file exceeds {self.limit / 2 ** 20:.0f} MB", source=source)
                if self.lines is not None and newlines > self.lines:  # a count so far: the rest is not read
                    raise InputError(f"{newlines:,} lines; robocal reads up to {self.said}", source=source)
            # what the file holds, else a chunk at a time, never ``limit`` bytes: a read of n bytes
            # reserves n first, and gigabytes reserved for a small file fail under an address-space
            # limit (ulimit -v)
            part = fh.read(min(max(size + 1 - total, READ_CHUNK), self.limit + 1 - total))
            if not part:
                if not out.tell():
                    return last, newlines
                out.write(last)
                return out.getvalue(), newlines


def available_memory() -> float | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), or None where unknown."""
    try:
        with open("/proc/meminfo", "rb") as fh:
            for line in fh:
                if line.startswith(b"MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _row_bound(most: int, per_gb: int | None) -> tuple[int, float | None]:
    """(the most data rows a table may hold now, the memory available or None where not counted)."""
    memory = available_memory() if per_gb else None
    return (most if memory is None or not per_gb else min(most, int(memory / 2 ** 30 * per_gb))), memory


def check_rows(raw: bytes, source: str, most: int, what: str = "poses", per_gb: int | None = None, *,
               newlines: int | None = None) -> None:
    """Refuse a file's bytes ``raw`` when they hold more than ``most`` data rows (lines that are not
    blank, not a ``#`` comment, and not the header), before any cell is parsed. ``per_gb``: also
    refuse more rows than that many per GB of memory available now. ``newlines``: the line ends of
    ``raw`` when counted already."""
    bound, memory = _row_bound(most, per_gb)
    newlines = raw.count(b"\n") if newlines is None else newlines
    returns = raw.count(b"\r") if b"\r" in raw else 0
    if max(newlines, returns) <= bound:  # at most bound + 1 lines: a header and ``bound`` rows
        return
    rows = sum(1 for ln in raw.splitlines() if ln.strip() and not ln.lstrip().startswith(b"#")) - 1
    if rows > most:
        raise InputError(f"{rows:,} rows; robocal reads up to {most:,} {what} per file (docs/formats.md)",
                         source=source)
    if memory is not None and rows > bound:
        raise InputError(f"{rows:,} rows; with {memory / 2 ** 30:.1f} GB of memory available robocal reads up "
                         f"to {bound:,} {what} ({per_gb:,} per GB, docs/formats.md)", source=source)


def decode(raw: bytes, source: str) -> str:
    """UTF-8 text (a BOM allowed); any other encoding is an InputError naming the line."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise InputError(f"not UTF-8 text ({e.reason} at byte {e.start}); save the file as UTF-8", source=source,
                         where=f"line {line}") from None
    if "\x00" in text:
        raise binary_error(raw, source, text[:text.index("\x00")].count("\n") + 1)
    return text


# the first bytes of every SQLite database file
SQLITE_MAGIC = b"SQLite format 3\x00"
# the first bytes of binary files a user may give where text goes: what each is, and what to do
BINARY_FORMS = ((b"#ROSBAG", "a ROS 1 bag, not text: `robocal import-bag` makes a measurement file of it"),
                (b"\x89MCAP", "a ROS 2 bag (MCAP), not text: `robocal import-bag` makes a measurement file of it"),
                (SQLITE_MAGIC, "an SQLite database (a store of calibrations, a ROS 2 bag's .db3), not text"),
                (b"PK\x03\x04", "a ZIP archive (a result's .npz holds its arrays; result.json is the result), "
                               "not text"))


def binary_error(head: bytes, source: str, line: int) -> InputError:
    """The error for a file holding a NUL character where text goes: what it is when ``head`` (its
    first bytes, or empty when not at hand) starts as a known binary file does (``BINARY_FORMS``),
    else the line of the NUL."""
    said = next((words for magic, words in BINARY_FORMS if head.startswith(magic)), None)
    if said is not None:
        return InputError(said, source=source)
    return InputError("a NUL character: this is a binary file, not text", source=source, where=f"line {line}")


def read_text(path, *, limit: int = MAX_FILE_BYTES, lines: int | None = None,
              rows: tuple[int, str, int | None] | None = None) -> tuple[str, str]:
    """The file's text (UTF-8, a BOM allowed) and the SHA-256 of its bytes; a missing, unreadable,
    oversized (``limit`` bytes, ``lines`` lines and ``rows`` when given: ``read_bytes``) or
    non-UTF-8 file is an InputError."""
    raw = read_bytes(path, limit=limit, lines=lines, rows=rows)
    if lines is not None:  # a table: the length of its lines, before the cells are split
        longest = max(map(len, raw.split(b"\n")))
        if longest > MAX_LINE_BYTES:
            raise InputError(f"a line of {longest:,} bytes; robocal reads lines of up to {MAX_LINE_BYTES:,} in a "
                             "table (docs/formats.md)", source=str(path))
    return decode(raw, str(path)), hashlib.sha256(raw).hexdigest()


# -- what a file is, from its first lines ----------------------------------------------------------

# a file's form is told from its first this many characters
SNIFFED_CHARS = 20_000
# the forms robocal imports into a model file: (the command, the function)
IMPORTED = {"urdf": ("import-urdf", "read_urdf"), "dh": ("import-dh", "read_dh_table")}


class FileForm(NamedTuple):
    """What a file holds, told from its first lines (``file_form``): ``key`` one of "model",
    "result" (or another robocal JSON file's kind: "limit", ...), "json", "urdf", "xml", "dh",
    "contacts", "measurements"; ``words`` the same for a message ("a URDF")."""

    key: str
    words: str


def file_form(head: str) -> FileForm | None:
    """The form of a file whose text begins with ``head``, when it is one of robocal's own files or a
    form robocal imports: a robocal model file (its ``robocal_model`` key), a robocal JSON file (its
    ``schema``), other JSON, a URDF (its ``<robot>`` element), other XML, a DH table (a header
    naming ``joint``, ``d``, ``alpha`` and ``theta`` columns), a contact file (``placement``,
    ``target`` and ``kind`` columns), a measurement file (a marker's ``NAME_x``, ``NAME_y``,
    ``NAME_z`` beside other columns); None for anything else."""
    text = head[:SNIFFED_CHARS].lstrip("\ufeff \t\r\n")
    if text.startswith("{"):
        schema = re.search(r'"schema"\s*:\s*"robocal\.([a-z_]+)/', text)
        return FileForm(schema.group(1), f"a robocal {schema.group(1)} file") if schema else \
            FileForm("json", "a JSON file")
    if text.startswith("<"):
        return FileForm("urdf", "a URDF") if re.search(r"<robot[\s>]", text) else FileForm("xml", "an XML file")
    if re.search(r"^robocal_model\s*:", text, re.MULTILINE):
        return FileForm("model", "a robocal model file")
    header = next((line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")), "")
    cells = {re.sub(r"_(deg|rad|mm|m)$", "", c.strip().strip('"').lower()) for c in re.split(r"[,;\t]", header)}
    if {"joint", "d", "alpha", "theta"} <= cells:
        return FileForm("dh", "a DH table")
    if {"placement", "target", "kind"} <= cells:
        return FileForm("contacts", "a contact file")
    if _measured_points(cells) and len(cells) > 3:     # a marker's x, y, z beside joint readings
        return FileForm("measurements", "a measurement file")
    return None


def _measured_points(cells: set[str]) -> bool:
    """Whether a header's ``cells`` (their units dropped) hold a marker's position, NAME_x, NAME_y, NAME_z."""
    return any(c.endswith("_x") and {c[:-1] + "y", c[:-1] + "z"} <= cells for c in cells if len(c) > 2)


# what to do with a file of each form given in another's place, whatever the place
FORM_HINTS = {"contacts": "`robocal calibrate MODEL --contacts FILE` (`read_contacts` in Python) reads it",
              "model": "a model file already, to give as the model",
              "measurements": "it is given after the model (`robocal calibrate MODEL DATA`; `read_measurements` in "
                              "Python)"}


def refuse_other_form(head: str, source: str, what: str, accepted: tuple[str, ...] = (),
                      hints: dict[str, str] | None = None) -> None:
    """InputError when the file whose text begins with ``head`` is of a form (``file_form``) other
    than the ``accepted`` ones, where ``what`` (its words: "a measurement file") is expected: the
    form named, with what to do (the command that imports it, else ``hints`` for the caller's own
    place, else ``FORM_HINTS``). A file of no known form is the caller's to read."""
    form = file_form(head)
    if form is None or form.key in accepted:
        return
    if form.key in IMPORTED:
        command, function = IMPORTED[form.key]
        hint = f"make a model file of it with `robocal {command} {source} --out model.yaml` (`rc.{function}` in Python)"
    else:
        hint = {**FORM_HINTS, **(hints or {})}.get(form.key, "")
    raise InputError(f"{form.words}, not {what}{': ' + hint if hint else ''}", source=source)


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

    def construct_object(self, node, deep=False):
        try:
            return super().construct_object(node, deep=deep)
        except InputError:
            raise
        except (ValueError, TypeError, ArithmeticError, LookupError, AttributeError) as e:  # !!float abc, !!bool x
            raise self.error(node, f"{excerpt(node.tag.rsplit(':', 1)[-1])} value "
                                   f"{excerpt(node.value if isinstance(node.value, str) else '...')} cannot be read "
                                   f"({type(e).__name__})") from None

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
    loader = None
    try:
        loader = _SafeLoader(text, source)  # its reader already refuses control characters
        return loader.get_single_data()
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        raise InputError(f"not valid YAML: {e.problem or e.context}", source=source, where=where) from None
    except yaml.reader.ReaderError as e:
        line = text[:e.position].count("\n") + 1
        char = f"#x{e.character:04x}" if isinstance(e.character, int) else repr(e.character)
        raise InputError(f"not valid YAML: character {char} is not allowed", source=source,
                         where=f"line {line}") from None
    except yaml.YAMLError as e:
        raise InputError(f"not valid YAML: {excerpt(str(e))}", source=source) from None
    finally:
        if loader is not None:
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
        raise InputError(f"not valid JSON: {e.msg}", source=source,
                         where=f"line {e.lineno}, column {e.colno}") from None
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

# the temporary file of an output NAME: ``.NAME.robocal-PID-RANDOM.tmp`` beside it; the process id
# tells a live run's temporary from the orphan of a run that was killed (SIGKILL, a power cut)
_TEMPORARY = re.compile(r"^\..+\.robocal-(?P<pid>[1-9][0-9]{0,9})-[0-9a-f]{16}\.tmp$")
# an output's name kept in its temporary's name: longer ones are cut, so the temporary's name fits
_NAME_IN_TEMPORARY = 100
_KINDS = ((stat.S_ISCHR, "a character device (a terminal, /dev/null...)"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a FIFO (a named or anonymous pipe)"), (stat.S_ISSOCK, "a socket"))


@accepts(path=PATH)
def sidecar_path(path) -> Path:
    """Where the per-pose arrays of the result file ``path`` go: beside it, ``.npz`` for ``.json``.
    (Here, with the other files' handling, so that a command names its outputs before it imports
    the results' machinery.)

    Parameters
    ----------
    {path}

    Returns
    -------
    pathlib.Path
        The per-pose file beside ``path`` (``.npz``).
    """
    return Path(path).with_suffix(".npz")


def check_replaceable(path) -> None:
    """Refuse, naming ``path``, an output that is not a regular file, a folder aside.

    A symbolic link is replaced (its target left alone) when it points to a regular file or to
    nothing; a device, a FIFO, a socket, or a link to one of them (``/dev/stdout``,
    ``/proc/self/fd/1``) is refused: robocal writes files, not streams (docs/formats.md).
    """
    p = str(path)
    try:
        st = os.lstat(p)
        if stat.S_ISLNK(st.st_mode):
            st = os.stat(p)
    except (FileNotFoundError, NotADirectoryError):
        return  # nothing there, or a link to nothing: written as a new file
    except OSError as e:
        if e.errno == errno.ELOOP:  # a link cycle: replaced like any link
            return
        raise InputError(f"cannot write: {e.strerror}", source=p) from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError("is a folder; give a file name", source=p)
    kind = next((what for test, what in _KINDS if test(st.st_mode)), None)
    if kind is not None or not stat.S_ISREG(st.st_mode):
        raise InputError(f"is {kind or 'not a regular file'}: robocal replaces only regular files; write to a "
                         "file and copy it from there", source=p)


def check_writable(paths, *, force: bool = False) -> None:
    """Before any work: each output can be written (its folder exists or can be made and is
    writable, the path is not a folder, a device or a FIFO) and, unless ``force``, does not exist yet."""
    for p in map(Path, paths):
        if "\x00" in str(p) or not str(p).strip():
            raise InputError("not a valid file name", source=excerpt(str(p)))
        check_replaceable(p)
        if not force and (p.exists() or p.is_symlink()):
            raise InputError("exists; pass --force to overwrite", source=str(p))
        folder = p.parent
        while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
            folder = folder.parent
        if not folder.is_dir():
            raise InputError(f"cannot write here: {folder} is a file, not a folder", source=str(p))
        try:  # a probe, not os.access: that says yes to root on a read-only disk
            fd, probe = _create(folder / ".robocal-probe")
            os.close(fd)
            os.unlink(probe)
        except OSError as e:
            raise InputError(f"cannot write in the folder {folder}: {e.strerror}", source=str(p)) from None


def _create(p: Path) -> tuple[int, str]:
    """A new empty file beside ``p`` under an unpredictable name (created exclusively, never through a
    link), with the mode a new file gets from the umask (0666 & ~umask): (descriptor, its path)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    while True:
        tmp = p.parent / f".{p.name[:_NAME_IN_TEMPORARY]}.robocal-{os.getpid()}-{secrets.token_hex(8)}.tmp"
        try:
            return os.open(tmp, flags, 0o666), str(tmp)
        except FileExistsError:  # 2**64 names: only a planted file gets here
            continue


def remove_orphans(folder) -> tuple[str, ...]:
    """Remove the temporary files an earlier robocal run left in ``folder`` when it was killed (their
    process is gone); the names removed. Links, folders and live runs' temporaries are left alone.

    For the ``robocal`` command in its own output folders only: a process id says nothing about
    another machine's run in a shared folder, so the library writers never call this."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return ()
    for entry in entries:
        m = _TEMPORARY.match(entry.name)
        if m is None or int(m["pid"]) == os.getpid() or _alive(int(m["pid"])):
            continue
        try:
            if entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
                removed.append(entry.path)
        except OSError:  # gone meanwhile, or not ours to remove
            pass
    return tuple(removed)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    except (OverflowError, OSError):
        return False
    return True


def write_texts(files: dict, *, force: bool = False) -> None:
    """Write several files ({path: text, or bytes for a binary file}) all-or-nothing: refuse if any
    exists (unless ``force``) or is not a regular file (a device, a FIFO, a link to one:
    ``check_replaceable``), write each to a fresh temporary file in its own folder (created
    exclusively under an unpredictable name, so a link planted there is never followed), and rename
    only once every write succeeded.

    The rename is atomic per file (``os.replace``; a link at the final name is replaced, not
    followed), so a reader never sees half a file. Files get the mode the umask gives a new file
    (0666 & ~umask). The temporary files are removed on every exception, Ctrl-C included; signal
    handlers and other files in the folders are the host program's and are left alone (the
    ``robocal`` command turns SIGTERM into an exception and removes its own orphans: ``cli``).
    Errors name the user's path.
    """
    paths = [Path(p) for p in files]
    for p in paths:
        check_replaceable(p)
        if not force and (p.exists() or p.is_symlink()):
            raise InputError("exists; pass force=True (--force) to overwrite", source=str(p))
    staged = []
    try:
        for p, text in zip(paths, files.values()):
            try:
                fd, tmp = _create(p)
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror}", source=str(p)) from None
            staged.append((tmp, p))
            try:
                binary = isinstance(text, bytes)
                fh = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8", newline="")
                with fh:
                    fh.write(text)
                    fh.flush()
                    os.fsync(fh.fileno())
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror}", source=str(p)) from None
        for _, p in staged:
            check_replaceable(p)  # again: a node put there during the work is refused, not replaced
        for tmp, p in staged:
            try:
                os.replace(tmp, p)
            except OSError as e:
                raise InputError(f"cannot write: {e.strerror}", source=str(p)) from None
    finally:
        for tmp, _ in staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
