"""Columnar CSV input and output of the command line: poses in, results out.

Reading goes through ``pyarrow.csv`` (multithreaded C++ parser, correctly rounded
float conversion), writing through ``pyarrow.csv.write_csv`` (shortest decimal
that converts back to the same double). Both keep every float exactly: a value
written and read back is bit-identical (``tests/io/test_csvio.py`` checks this
with hypothesis). ``pyarrow`` is imported only when a CSV is read or written.

Any file the fast reader does not accept as clean numbers (a bad value, a
short row, whitespace around a number, ...) is read again by the plain
:mod:`csv` reader, which either accepts it or names the file, the line, the
column and the problem in a :class:`~pmaccuracy.errors.ConfigError`.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from pathlib import Path
from typing import IO, NoReturn

import numpy as np

from .._textfile import read_text
from ..errors import ConfigError

#: Columns a poses CSV must name (mm, mm, deg); other columns are ignored.
POSE_COLUMNS = ("x", "y", "phi_deg")


def _header(path: str) -> list[str]:
    """The first CSV row with each name stripped; ``[]`` for an empty file or a blank first line."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            return [h.strip() for h in next(csv.reader(fh), [])]
    except FileNotFoundError:
        raise ConfigError("no such file", source=path) from None
    except IsADirectoryError:
        raise ConfigError("is a folder, not a CSV file", source=path) from None
    except UnicodeDecodeError:
        _not_text(path)
    except csv.Error as exc:
        raise ConfigError(f"malformed CSV header ({exc})", source=path, key="line 1") from None


def _not_text(path: str) -> NoReturn:
    """Refuse a file that is not UTF-8 text, naming the line of its first foreign byte (it is decoded again,
    whole, by :func:`pmaccuracy._textfile.read_text`, which raises)."""
    read_text(path, what="CSV file")
    raise ConfigError("not a UTF-8 text CSV file", source=path)


def read_poses_csv(path: str | Path, columns: tuple[str, ...] | None = None) -> np.ndarray:
    """Poses from a CSV whose header names the columns ``x``, ``y``, ``phi_deg`` (mm, mm, deg) -> ``(N, 3)``
    (or the given ``columns``, e.g. a spatial robot's ``x, y, z, roll_deg, pitch_deg, yaw_deg``).

    Other columns are ignored (so a map written by ``pmaccuracy map --out FILE.csv``
    feeds back into ``pmaccuracy bounds --poses-csv``); blank lines are skipped; a
    UTF-8 byte-order mark (as Excel writes) is accepted.
    The values are returned exactly as written (correctly rounded doubles), still
    in degrees for ``phi_deg``.

    Raises
    ------
    ConfigError : missing file, missing columns, a row of the wrong length, a
        non-numeric or non-finite value (naming the line and the column), no poses
    """
    path = str(path)
    columns = tuple(columns or POSE_COLUMNS)
    header = _header(path)
    missing = [c for c in columns if c not in header]
    if missing:
        raise ConfigError(f"header must name the columns {','.join(columns)} (missing {','.join(missing)}), "
                          f"got {','.join(header)!r}", source=path)
    cols = [header.index(c) for c in columns]
    poses = _read_fast(path, len(header), cols)
    if poses is None:  # something the fast reader did not take: the careful reader explains or accepts it
        poses = _read_careful(path, header, cols, columns)
    if poses.shape[0] == 0:
        raise ConfigError("no poses in file", source=path)
    return poses


def _read_fast(path: str, n_columns: int, cols: list[int]) -> np.ndarray | None:
    """pyarrow's reader on clean files; ``None`` when it refuses the file or a value is missing or non-finite."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    names = [f"c{j}" for j in range(n_columns)]
    wanted = [names[j] for j in cols]
    try:
        table = pcsv.read_csv(
            path,
            read_options=pcsv.ReadOptions(column_names=names, skip_rows=1),
            parse_options=pcsv.ParseOptions(newlines_in_values=False),
            convert_options=pcsv.ConvertOptions(include_columns=list(dict.fromkeys(wanted)),
                                                column_types={n: pa.float64() for n in wanted},
                                                null_values=[], quoted_strings_can_be_null=False))
    except (pa.ArrowException, UnicodeDecodeError):  # the careful reader names the problem
        return None
    if any(table.column(n).null_count for n in wanted):
        return None
    out = np.empty((table.num_rows, len(cols)))
    for k, n in enumerate(wanted):
        _copy_column(table.column(n), out[:, k])
    if not np.isfinite(out).all():
        return None
    return out


def _copy_column(column, out: np.ndarray) -> None:
    """Copy a float64 pyarrow column without nulls into ``out`` ``(n,)``, chunk by chunk from its data buffers.

    (``to_numpy`` gives the same values but imports pandas on its first call, about 0.4 s of the command's
    start; issue 35.)"""
    pos = 0
    for chunk in column.chunks:
        count = len(chunk)
        data = chunk.buffers()[1]       # [validity bitmap (none: no nulls), values]
        out[pos:pos + count] = np.frombuffer(data, dtype="<f8", count=chunk.offset + count)[chunk.offset:]
        pos += count


def _read_careful(path: str, header: list[str], cols: list[int], columns: tuple[str, ...] = POSE_COLUMNS
                  ) -> np.ndarray:
    """The plain :mod:`csv` reader: same result as the fast one on clean files, a precise error otherwise."""
    rows = []
    reader = None
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            next(reader, None)
            for row in reader:
                line = reader.line_num
                if not row or all(not c.strip() for c in row):
                    continue
                if len(row) != len(header):
                    raise ConfigError(f"expected {len(header)} values, got {len(row)}", source=path,
                                      key=f"line {line}")
                values = []
                for j, name in zip(cols, columns):
                    try:
                        v = float(row[j])
                    except ValueError:
                        raise ConfigError(f"non-numeric value {row[j]!r} in column {name}", source=path,
                                          key=f"line {line}") from None
                    if not math.isfinite(v):
                        raise ConfigError(f"non-finite value {row[j]!r} in column {name}", source=path,
                                          key=f"line {line}")
                    values.append(v)
                rows.append(values)
    except UnicodeDecodeError:
        _not_text(path)
    except csv.Error as exc:  # e.g. a field longer than csv.field_size_limit() (131072 characters)
        where = f"line {reader.line_num}" if reader is not None and reader.line_num else None
        raise ConfigError(f"malformed CSV ({exc})", source=path, key=where) from None
    return np.array(rows, dtype=float).reshape(-1, len(columns))


def float_table(columns: Mapping[str, np.ndarray]):
    """A ``pyarrow.Table`` of float64 columns over the arrays' own memory (copied only when not contiguous float64).

    Built from the data buffers: ``pyarrow.array`` on numpy values gives the same table but imports pandas on
    its first call (about 0.4 s of the command's start; issue 35)."""
    import pyarrow as pa

    arrays = []
    for name in columns:
        values = np.ascontiguousarray(columns[name], dtype=float).reshape(-1)
        arrays.append(pa.Array.from_buffers(pa.float64(), values.size, [None, pa.py_buffer(values)]))
    return pa.Table.from_arrays(arrays, names=list(columns))


def write_csv_columns(columns: Mapping[str, np.ndarray], stream: IO[str] | IO[bytes] | str | Path) -> None:
    """Write equal-length float columns as CSV: a header of the names, then one row per element.

    Floats are written as the shortest decimal that reads back as the same
    double (``0.1``, ``1e-05`` as ``0.00001``, ``100.0`` as ``100``), NaN as ``nan``;
    ``stream`` is a text or binary stream or a file path.
    """
    import pyarrow.csv as pcsv

    names = list(columns)
    if any("," in n or '"' in n or "\n" in n for n in names):
        raise ValueError(f"column names must not need quoting: {names}")
    table = float_table(columns)
    header = (",".join(names) + "\n").encode()
    options = pcsv.WriteOptions(include_header=False, quoting_style="none", batch_size=1 << 16)
    if isinstance(stream, (str, Path)):
        with open(stream, "wb") as fh:
            fh.write(header)
            pcsv.write_csv(table, fh, options)
        return
    buffer = getattr(stream, "buffer", None)
    if buffer is not None:  # a text stream over a binary one (sys.stdout): write the bytes underneath
        stream.flush()
        buffer.write(header)
        pcsv.write_csv(table, buffer, options)
        buffer.flush()
        return
    if isinstance(stream, io.TextIOBase):  # a text stream without bytes underneath (io.StringIO)
        sink = io.BytesIO()
        pcsv.write_csv(table, sink, options)
        stream.write(header.decode() + sink.getvalue().decode())
        return
    stream.write(header)  # a binary stream
    pcsv.write_csv(table, stream, options)


def _g6_length_bound(values: np.ndarray) -> np.ndarray:
    """Upper bound of ``len(f"{v:.6g}")`` for each value (exact unless ``%g`` strips trailing zeros)."""
    v = np.asarray(values, dtype=float)
    sign = np.signbit(v).astype(int)
    with np.errstate(divide="ignore", invalid="ignore"):
        exp10 = np.floor(np.log10(np.abs(v)))
    finite = np.isfinite(v) & (v != 0)
    # %.6g uses exponent form below 1e-4 and from 1e6 on (a rounding up to 1e6 only gets shorter)
    fixed = finite & (exp10 >= -4) & (exp10 < 6)
    fixed_len = sign + np.where(exp10 >= 0, 7, 2 + (-exp10 - 1) + 6)  # 123.457 / 0.000123457
    exp_len = sign + 7 + np.where(np.abs(exp10) >= 100, 5, 4)  # d.ddddde+XX
    other = np.where(np.isnan(v), 3, np.where(np.isinf(v), 3 + sign, 1 + sign))  # nan, inf, -inf, 0, -0
    return np.where(fixed, fixed_len, np.where(finite, exp_len, other)).astype(int)


def _g6_width(values: np.ndarray) -> int:
    """``max(len(f"{v:.6g}"))`` over the values, formatting only the few that may be the widest."""
    values = np.asarray(values, dtype=float).reshape(-1)
    if values.size == 0:
        return 0
    bound = _g6_length_bound(values)
    best = 0
    for b in np.unique(bound)[::-1]:
        if b <= best:
            break
        for v in values[bound == b].tolist():
            best = max(best, len(f"{v:.6g}"))
            if best == b:
                break
    return best


def write_table_columns(columns: Mapping[str, np.ndarray], stream: IO[str], block: int = 1 << 16) -> None:
    """Right-aligned text table of float columns, 6 significant digits (``%.6g``), NaN as ``nan``.

    Column widths come from :func:`_g6_width`, then the rows are formatted and
    written block by block (memory of one block of text).
    """
    names = list(columns)
    arrays = [np.asarray(columns[n], dtype=float).reshape(-1) for n in names]
    widths = [max(len(n), _g6_width(a)) for n, a in zip(names, arrays)]
    stream.write("  ".join(n.rjust(w) for n, w in zip(names, widths)) + "\n")
    row = "  ".join(f"%{w}.6g" for w in widths) + "\n"   # printf-style: about twice as fast as str.format
    n_rows = len(arrays[0]) if arrays else 0
    for start in range(0, n_rows, block):
        lists = [a[start:start + block].tolist() for a in arrays]
        stream.write("".join([row % r for r in zip(*lists)]))


def format_columns(columns: Mapping[str, np.ndarray], fmt: str, stream: IO[str]) -> None:
    """Write float columns in the CLI's ``--format`` (``csv``, ``table`` or ``json``: a list of records)."""
    if fmt == "csv":
        write_csv_columns(columns, stream)
    elif fmt == "table":
        write_table_columns(columns, stream)
    elif fmt == "json":
        import json

        names = list(columns)
        lists = [[v if math.isfinite(v) else None for v in np.asarray(columns[n], dtype=float).tolist()]
                 for n in names]
        json.dump([dict(zip(names, row)) for row in zip(*lists)], stream, indent=2)
        stream.write("\n")
    else:
        raise ValueError(f"unknown format {fmt!r}")
