"""JSON text from users and files, read without letting hostile input raise past the reader.

``json.loads`` raises more than ``JSONDecodeError``: a RecursionError for deep nesting and a
ValueError for an integer over Python's 4,300-digit limit. :func:`parse_json` turns all three
into :class:`JsonProblem`, with the column where one is known.
"""

from __future__ import annotations

import json
import sys

from rasm.errors import RasmError

__all__ = ["JsonProblem", "parse_json"]


class JsonProblem(RasmError, ValueError):
    """Why a JSON text could not be read, and the column (1-based) where that is known."""

    def __init__(self, message: str, column: int = 1) -> None:
        super().__init__(message)
        self.message = message
        self.column = column


def parse_json(text: str) -> object:
    """``json.loads(text)``; any failure is a :class:`JsonProblem` that says what is wrong."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise JsonProblem(f"not valid JSON: {exc.msg}", exc.colno) from None
    except RecursionError:
        limit = sys.getrecursionlimit()
        raise JsonProblem(f"nested too deeply (more than about {limit} levels)") from None
    except ValueError:  # Python's int-string conversion limit
        limit = sys.get_int_max_str_digits()
        raise JsonProblem(f"cannot be read: an integer longer than {limit} digits") from None
