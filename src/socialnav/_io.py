"""Files every package writes and reads safely: atomic writes, directory locks, checksums.

The layer below every package (docs/internals.md, "Layers"): results, trajectories, checkpoints,
training curves, maps and reports are all written through :func:`atomic_write`.

Atomic writes: write to a temporary file in the same directory, then rename.

A reader (or a resumed run) therefore sees either the previous complete file or the new complete
file, never a partial one, even if the process is killed mid-write. The file gets the permissions a
plain ``open()`` would give it (0666 masked by the process umask), not the temporary file's 0600, so
colleagues on a shared server can read results. JSON files hold ``null`` where a value is NaN or
infinite (JSON has no NaN).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any


def atomic_write(path: Path, write: Callable[[str], object]) -> None:
    """Calls ``write(tmp_path)`` and renames the result onto ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, default_file_mode())
        os.replace(tmp, path)
    except BaseException as err:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(err, OSError) and err.filename is None:  # e.g. a full disk: say which file
            raise OSError(err.errno, f"cannot write {path}: {err.strerror or err}") from None
        raise


def process_umask() -> int:
    """The process umask, read without changing it where the OS allows (Linux: /proc)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # the only portable way to read it; restored at once
    os.umask(mask)
    return mask


def default_file_mode() -> int:
    """Mode of a newly created regular file: 0666 minus the umask (temporary files get 0600)."""
    return 0o666 & ~process_umask()


def make_output_dir(out: Path) -> None:
    """Creates ``out`` (and parents), refusing a path through a file or a directory it cannot write."""
    for parent in [out, *out.parents]:
        if parent.exists() and not parent.is_dir():
            raise NotADirectoryError(f"--out {out}: {parent} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK | os.X_OK):
        raise PermissionError(f"--out {out}: directory is not writable")


def json_safe(value: Any) -> Any:
    """Convert ``value`` to what ``json.dumps(allow_nan=False)`` accepts.

    NaN and inf become None, NumPy scalars and arrays become Python values, tuples become lists; the input is
    not modified.
    """
    import math

    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, str | bytes):  # NumPy scalar or array
        return json_safe(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def atomic_write_text(path: Path, text: str) -> None:
    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())

    atomic_write(path, write)


def atomic_write_json(path: Path, data: Any) -> None:
    atomic_write_text(path, json_text(data))


def json_text(data: Any) -> str:
    """The text :func:`atomic_write_json` writes (NaN and infinities as null, numpy values as numbers)."""
    text = json.dumps(json_safe(data), indent=2, sort_keys=False, default=_json_default, allow_nan=False)
    return text + "\n"


def atomic_write_rows_parquet(
    path: Path, rows: list[dict[str, Any]], metadata: dict[str, str] | None = None
) -> None:
    """Writes ``rows`` as Parquet with page checksums; ``metadata`` goes in the file's key-value metadata."""
    atomic_write_bytes(path, rows_parquet_bytes(rows, metadata))


def atomic_write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))


def rows_parquet_bytes(rows: list[dict[str, Any]], metadata: dict[str, str] | None = None) -> bytes:
    """Serialise ``rows`` to the bytes of a Parquet file with page checksums.

    A sweep's worker builds a chunk's file this way and the driver, which alone writes results, stores it.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows)
    if metadata:
        table = table.replace_schema_metadata({**(table.schema.metadata or {}), **metadata})
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, write_page_checksum=True)
    return sink.getvalue().to_pybytes()


def read_parquet_verified(path: Path, filters: Any = None, data: bytes | None = None):
    """Read a Parquet file, verifying its page checksums.

    A damaged file is an error naming it. With ``data``, the file's bytes are read from memory (``path`` names
    them in errors).

    Raises:
        CorruptFileError: The file is truncated, not Parquet, or a page fails its checksum.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        source = path if data is None else pa.BufferReader(data)
        return pq.read_table(source, page_checksum_verification=True, filters=filters)
    except (OSError, pa.ArrowException) as err:
        if isinstance(err, FileNotFoundError | IsADirectoryError | PermissionError):
            raise
        raise CorruptFileError(f"{path}: damaged or not a Parquet file ({_one_line(err)})") from None


class CorruptFileError(ValueError):
    """A result or input file that cannot be trusted (truncated, or failing its checksums)."""


class DirectoryLockedError(RuntimeError):
    """Another process is writing to the same output directory."""


class DirectoryLock:
    """An exclusive advisory lock on a directory (``.lock`` inside it), held while a run writes there.

    The kernel drops the lock when the holder exits, however it dies, so a killed run never leaves a
    stale lock behind. A second run on the same directory is refused at once instead of interleaving.
    """

    def __init__(self, directory: Path, what: str = "run") -> None:
        self.directory = Path(directory)
        self.what = what
        self._fd: int | None = None

    def __enter__(self) -> DirectoryLock:
        import fcntl

        path = self.directory / ".lock"
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise DirectoryLockedError(
                f"{self.directory} is in use by another {self.what} (pid {holder}); "
                "wait for it to finish or use another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd
        return self

    def __exit__(self, *exc: object) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing releases the lock; the file stays (removing it would race)
            self._fd = None


def remove_orphan_temporaries(directory: Path) -> list[Path]:
    """Deletes ``.*.tmp`` files left under ``directory`` by a killed writer (call under the lock)."""
    removed = []
    for tmp in Path(directory).rglob(".*.tmp"):
        if tmp.is_file():
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
    return removed


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__


def _json_default(value: Any) -> Any:
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


# --------------------------------------------------------------------------------------- messages
def short_repr(value: Any, limit: int = 80, *, json_style: bool = False) -> str:
    """``repr(value)`` for a message, cut to ``limit`` characters (ending ``...``) where longer.

    Only the first ``limit`` or so characters are ever rendered: a value read from a file may hold
    millions of items (or one integer of a million digits), and building its whole repr to keep 80
    characters of it would take as long and as much memory as the value itself.

    Args:
        value: Any value; lists, tuples, sets and mappings are walked, anything else is ``repr``'d
            (strings and bytes after cutting them to ``limit``).
        limit: The most characters returned (at least 4).
        json_style: Write ``null``, ``true``, ``false`` and ``"text"``, as ``json.dumps`` does.

    Returns:
        The text, at most ``limit`` characters.
    """
    parts: list[str] = []
    used = 0

    class Full(Exception):
        pass

    def put(text: str) -> None:
        nonlocal used
        parts.append(text)
        used += len(text)
        if used > limit:
            raise Full

    def items(open_: str, close: str, values: Any, single: str = "") -> None:
        put(open_)
        n = 0
        for n, item in enumerate(values, 1):
            if n > 1:
                put(", ")
            walk(item)
        put(single if n == 1 else "")
        put(close)

    def walk(v: Any) -> None:
        if isinstance(v, str | bytes):
            cut = v[: limit + 1]
            put(json.dumps(cut) if json_style and isinstance(cut, str) else repr(cut))
        elif json_style and (v is None or isinstance(v, bool | float)):
            put(json.dumps(v))
        elif isinstance(v, int) and not isinstance(v, bool) and v.bit_length() > 4 * limit:
            put(f"<an integer of {int(v.bit_length() * 0.30103) + 1} digits>")  # repr: over the limit
        elif isinstance(v, dict):
            put("{")
            for n, (key, item) in enumerate(v.items()):
                if n:
                    put(", ")
                walk(str(key) if json_style else key)
                put(": ")
                walk(item)
            put("}")
        elif isinstance(v, list) or (json_style and isinstance(v, tuple)):
            items("[", "]", v)
        elif type(v) is tuple:
            items("(", ")", v, single=",")
        elif type(v) in (set, frozenset) and v:
            items("{" if type(v) is set else "frozenset({", "}" if type(v) is set else "})", v)
        else:
            put(repr(v))

    try:
        walk(value)
    except Full:
        return "".join(parts)[: max(limit - 3, 1)] + "..."
    return "".join(parts)


# ------------------------------------------------------------------------------------------- YAML
#: The most values (scalars, lists, mappings) a YAML document may expand to, an alias (``*name``)
#: counted with everything its anchor holds each time it is used. A preset or sweep holds hundreds, a
#: map of 100 000 two-point walls 700 000 (7 a wall); ten nested anchors of ten aliases each ("billion
#: laughs") expand a few hundred bytes to 10^10 values, which every later walk over them (validation,
#: copies, messages) would visit.
YAML_MAX_NODES = 1_000_000
#: The deepest nesting of lists and mappings (aliases followed) in a YAML document, and of elements in
#: an SVG map: the readers walk them recursively, and no settings or map file nests more than ten.
MAX_NESTING_DEPTH = 100

_STRICT_LOADER: Any = None


def load_yaml(text: str) -> Any:
    """``yaml.safe_load``, refusing a mapping that gives one key twice, and reading ``1e-2`` as a number.

    PyYAML keeps the last of two equal keys without a word, so a preset, training config, sweep or map
    file with a block pasted twice (two ``walls:``, two ``world:``) would silently lose the first.
    Every user YAML (and JSON) file is read through this.

    The document is refused before any value is built where it nests deeper than
    :data:`MAX_NESTING_DEPTH` or expands, its aliases followed, to more than :data:`YAML_MAX_NODES`
    values, or where an alias refers to a list or mapping that holds it (an endless value): the check
    costs one count per node of the document as written, however far the aliases would expand it.

    Raises:
        yaml.YAMLError: Not valid YAML, a repeated key (the message names it and both lines), a value
            that cannot be built (e.g. an integer of more than 4300 digits), or a document over the
            limits above (the message names the limit and the line).
    """
    import yaml

    global _STRICT_LOADER
    if _STRICT_LOADER is None:
        _STRICT_LOADER = _strict_loader(yaml)
    return yaml.load(text, Loader=_STRICT_LOADER)  # noqa: S506  (a SafeLoader subclass)


def _strict_loader(yaml: Any) -> Any:
    """The SafeLoader subclass of :func:`load_yaml` (built on first use: PyYAML is imported lazily)."""
    from yaml.composer import ComposerError
    from yaml.constructor import ConstructorError
    from yaml.events import AliasEvent

    class StrictLoader(yaml.SafeLoader):
        def compose_document(self) -> Any:
            # per node of the document: (values it expands to, nesting depth), aliases followed
            self.expanded: dict[int, tuple[int, int]] = {}
            self.depth = 0
            return super().compose_document()

        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(AliasEvent):
                event = self.peek_event()
                target = self.anchors.get(event.anchor)
                if target is not None and id(target) not in self.expanded:  # an anchor still open
                    raise ComposerError(
                        None, None, f"the alias *{event.anchor} refers to a list or mapping that holds it "
                        "(an endless value)", event.start_mark)
                return super().compose_node(parent, index)
            self.depth += 1
            if self.depth > MAX_NESTING_DEPTH:
                raise ComposerError(
                    None, None, f"nested too deep: more than {MAX_NESTING_DEPTH} levels of lists and "
                    "mappings", self.peek_event().start_mark)
            try:
                node = super().compose_node(parent, index)
            finally:
                self.depth -= 1
            self._count(node)
            return node

        def _count(self, node: Any) -> None:
            """Records what ``node`` expands to; its children (aliases: their anchors) are counted."""
            if isinstance(node, yaml.MappingNode):
                children = [child for pair in node.value for child in pair]
            elif isinstance(node, yaml.SequenceNode):
                children = node.value
            else:
                children = []
            counts = [self.expanded[id(child)] for child in children]
            nodes = 1 + sum(n for n, _ in counts)
            depth = 1 + max((d for _, d in counts), default=0)
            if depth > MAX_NESTING_DEPTH:
                raise ComposerError(
                    None, None, f"nested too deep: more than {MAX_NESTING_DEPTH} levels of lists and "
                    "mappings once its aliases are followed", node.start_mark)
            if nodes > YAML_MAX_NODES:
                raise ComposerError(
                    None, None, f"the document expands to more than {YAML_MAX_NODES:,} values (each "
                    "*alias counts everything its &anchor holds, each time it is used; a few hundred bytes "
                    "of nested anchors can stand for billions), the limit for a settings or map file",
                    node.start_mark)
            self.expanded[id(node)] = (nodes, depth)

        def construct_object(self, node: Any, deep: bool = False) -> Any:
            try:
                return super().construct_object(node, deep)
            except ValueError as err:  # e.g. an integer of more than 4300 digits, a date 2024-13-01
                raise ConstructorError(None, None, f"cannot read the value: {_one_line(err).split(';')[0]}",
                                       node.start_mark) from None

    def construct_mapping(loader: Any, node: Any, deep: bool = False) -> Any:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # `<<: *base`: keys given here override it
                continue
            key = loader.construct_object(key_node, deep=True)
            try:
                first = seen.get(key)
            except TypeError:  # an unhashable key: PyYAML refuses it below, in its own words
                continue
            line = key_node.start_mark.line + 1
            if first is not None:
                where = f"line {line}" if first == line else f"lines {first} and {line}"
                raise ConstructorError(
                    None, None, f"key {short_repr(key)} is given twice ({where}); only one can hold",
                    key_node.start_mark)
            seen[key] = line
        return yaml.SafeLoader.construct_mapping(loader, node, deep)

    StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, construct_mapping)
    # YAML 1.1 reads 1e-2 (no dot) as text; every number a user writes so is meant as a number
    StrictLoader.add_implicit_resolver(
        "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
        list("-+0123456789"),
    )
    return StrictLoader
