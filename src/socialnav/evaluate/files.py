"""Deprecated alias of :mod:`socialnav._io`.

Moved to :mod:`socialnav._io` (the I/O layer below every package); this name is kept for scripts written
against earlier releases that import ``socialnav.evaluate.files``.
"""

from socialnav._io import (
    CorruptFileError,
    DirectoryLock,
    DirectoryLockedError,
    atomic_write,
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_rows_parquet,
    atomic_write_text,
    default_file_mode,
    file_sha256,
    json_safe,
    json_text,
    make_output_dir,
    read_parquet_verified,
    remove_orphan_temporaries,
    rows_parquet_bytes,
)

__all__ = [
    "CorruptFileError",
    "DirectoryLock",
    "DirectoryLockedError",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_rows_parquet",
    "atomic_write_text",
    "default_file_mode",
    "file_sha256",
    "json_safe",
    "json_text",
    "make_output_dir",
    "read_parquet_verified",
    "remove_orphan_temporaries",
    "rows_parquet_bytes",
]
