"""The result file (JSON): ``CalibrationResult.to_dict()`` with its schema version (docs/formats.md)."""

from __future__ import annotations

import json
import math

import numpy as np

from .._errors import InputError
from .model import read_text, write_texts

SCHEMAS = ("robocal.result/1",)


def _plain(obj):
    """JSON-ready copy: numpy types to Python, NaN and infinities to null (strict JSON has neither)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def result_to_json(result) -> str:
    """The result file text of a CalibrationResult (or of its ``to_dict()``)."""
    d = result if isinstance(result, dict) else result.to_dict()
    return json.dumps(_plain(d), indent=1, allow_nan=False) + "\n"


def write_result(result, path, *, force: bool = False) -> None:
    """Write ``result.to_dict()`` as JSON, atomically; an existing file is an InputError unless ``force``."""
    write_texts({path: result_to_json(result)}, force=force)


def read_result(path) -> dict:
    """The dict stored by ``write_result``; InputError if it is not a robocal result of a known schema."""
    source = str(path)
    text, _ = read_text(path)
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON: {e.msg}", source=source, where=f"line {e.lineno}, column {e.colno}") from None
    if not isinstance(d, dict) or "schema" not in d:
        raise InputError("not a robocal result: no 'schema' key", source=source, where="schema")
    if d["schema"] not in SCHEMAS:
        raise InputError(f"unknown schema {d['schema']!r}; this robocal reads {', '.join(SCHEMAS)}", source=source,
                         where="schema")
    return d
