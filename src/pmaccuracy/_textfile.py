"""Reading the user's text files (TOML, JSON, CSV) so that every problem names the file and, when known, the line.

Files are read as bytes and decoded here: a binary file (NUL bytes: an image, a
spreadsheet, UTF-16 text) or one saved in another encoding than UTF-8 (latin-1,
cp1252) is refused naming the file (and for another encoding the line of the
first byte that is not UTF-8), instead of escaping as a
:class:`UnicodeDecodeError`. A UTF-8 byte-order mark (as Excel writes) is dropped.
CSV rows come with the line they start on, and a CSV the
:mod:`csv` module cannot split (a cell longer than its field limit of 131 072
characters, even in a column the reader then ignores) is refused naming the line.

``error`` is the exception to raise: a :class:`~pmaccuracy.errors.ConfigError`
subclass (built with ``source`` the file and ``key`` ``"line N"``), or any callable
``error(message, line)`` returning an exception (line ``None`` when unknown).
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Callable
from pathlib import Path
from typing import Union

from .errors import ConfigError

ErrorFactory = Union[type[ConfigError], Callable[[str, "int | None"], Exception]]

_BOM = b"\xef\xbb\xbf"


def _factory(error: ErrorFactory, source: str) -> Callable[[str, "int | None"], Exception]:
    if isinstance(error, type) and issubclass(error, ConfigError):
        return lambda message, line=None: error(message, source=source,
                                                key=None if line is None else f"line {line}")
    return error


def read_bytes(path: str | os.PathLike, error: ErrorFactory = ConfigError, *, what: str = "file") -> bytes:
    """The file's bytes; a missing file, a folder or an unreadable file raises ``error`` naming it."""
    fail = _factory(error, str(path))
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise fail("no such file", None) from None
    except IsADirectoryError:
        raise fail(f"is a folder, not a {what}", None) from None
    except OSError as exc:
        raise fail(f"cannot read ({exc.strerror or exc})", None) from None


def decode(data: bytes, source: str, error: ErrorFactory = ConfigError) -> str:
    """UTF-8 text of ``data`` (a leading byte-order mark dropped); ``error`` naming the line of the first byte
    that is not text otherwise."""
    fail = _factory(error, source)
    if data.startswith(_BOM):
        data = data[len(_BOM):]
    if b"\0" in data:
        raise fail("a binary file, not text (it holds NUL bytes; a UTF-16 text file: save it as UTF-8)", None)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise fail(f"not UTF-8 text (byte 0x{data[exc.start]:02x}): a binary file, or text in another encoding "
                   f"(latin-1, cp1252): save it as UTF-8", data.count(b"\n", 0, exc.start) + 1) from None


def read_text(path: str | os.PathLike, error: ErrorFactory = ConfigError, *, what: str = "file") -> str:
    """The text of a UTF-8 file (:func:`read_bytes`, :func:`decode`)."""
    return decode(read_bytes(path, error, what=what), str(path), error)


def csv_rows(text: str, source: str, error: ErrorFactory = ConfigError) -> list[tuple[int, list[str]]]:
    """Every row of CSV ``text`` with the line it starts on (1 for the header); blank lines give ``[]``."""
    fail = _factory(error, source)
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[tuple[int, list[str]]] = []
    start = 1
    try:
        for row in reader:
            rows.append((start, row))
            start = reader.line_num + 1
    except csv.Error as exc:
        if "field limit" in str(exc):
            message = f"a cell longer than {csv.field_size_limit()} characters (not a CSV of numbers?)"
        else:
            message = f"malformed CSV ({exc})"
        raise fail(message, reader.line_num or start) from None
    return rows


def read_csv(path: str | os.PathLike, error: ErrorFactory = ConfigError) -> list[tuple[int, list[str]]]:
    """The rows of a UTF-8 CSV file with their lines (:func:`read_text`, :func:`csv_rows`)."""
    return csv_rows(read_text(path, error, what="CSV file"), str(path), error)
