"""Reading an identification record from its file: the JSON that ``calibrate identify --out`` writes
(:func:`~pmaccuracy.accuracy.calibration.identify.identification_to_dict`, or for a spatial robot
:func:`~pmaccuracy.accuracy.calibration.spatial_identify.spatial_identification_to_dict`)."""

from __future__ import annotations

import json
import os

from ..._textfile import read_text
from ...errors import ConfigError, PmAccuracyError
from ...model.spatial import is_spatial_architecture
from .identify import Identification, identification_from_dict
from .spatial_identify import SpatialIdentification, spatial_identification_from_dict


def read_identification(path: str | os.PathLike) -> Identification | SpatialIdentification:
    """The identification stored in a JSON file written by ``calibrate identify --out`` (a spatial robot's:
    a :class:`~.spatial_identify.SpatialIdentification`).

    Raises :class:`~pmaccuracy.errors.ConfigError` naming the file (and the line of a JSON syntax error, or the
    key of a malformed record): a missing, binary or non-UTF-8 file, text that is not JSON, JSON that is not an
    identification record.
    """
    src = os.fspath(path)
    text = read_text(src, what="identification JSON file")
    try:
        record = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not JSON: {exc.msg} (column {exc.colno})", source=src, key=f"line {exc.lineno}") from None
    except RecursionError:
        raise ConfigError("not an identification record: JSON nested too deeply", source=src) from None
    if not isinstance(record, dict):
        raise ConfigError(f"not an identification record: a JSON {type(record).__name__}, not an object written by "
                          "calibrate identify --out", source=src)
    try:
        table = record.get("robot")
        if isinstance(table, dict) and is_spatial_architecture(table.get("architecture")):
            return spatial_identification_from_dict(record, source=src)
        return identification_from_dict(record, source=src)
    except PmAccuracyError as exc:
        if src in str(exc):
            raise
        raise ConfigError(str(exc), source=src) from None
    except (AttributeError, IndexError, OverflowError, TypeError, ValueError, KeyError) as exc:
        raise ConfigError(f"not an identification record written by calibrate identify --out "
                          f"({type(exc).__name__}: {exc})", source=src) from None
