"""Reading a few fields straight out of CDR bytes, without decoding the rest of the message.

``rasm check`` on a recording reads one or two fields of each message (``twist.twist.linear.x``
of an Odometry); decoding whole messages to read them costs several times more than the
reading. :func:`field_reader` plans, once per type and set of field paths, how to walk a
message's CDR: fixed-size parts are stepped over by arithmetic, strings and sequences by their
lengths, and only the wanted fields are unpacked.

The walk checks the message as rosbags' decoder does (every string's length, terminator and
UTF-8, every sequence's length, the total size), so a message is accepted exactly when its
whole decoding would be; :class:`MalformedMessage` otherwise.

A path is served when it runs through plain sub-messages to a primitive or string field, a
whole array or sequence of primitives or strings, or one element of an array or sequence of
primitives (``ranges[3]``; an index past the end gives :data:`MISSING`). Other paths (a whole
sub-message, a field inside an array of messages) are read from the whole decoded message.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.interfaces import Nodetype

from rasm.ros2.errors import MalformedMessage
from rasm.ros2.fields import FieldPath, field_type

if TYPE_CHECKING:
    from rasm.ros2.types import TypeStore

__all__ = ["MISSING", "field_reader", "projection", "serves"]

MISSING = object()  # the value of an element past the end of its sequence

_SIZES = {
    "bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
    "int32": 4, "uint32": 4, "int64": 8, "uint64": 8, "float32": 4, "float64": 8,
}
_FORMATS = {
    "bool": "?", "byte": "B", "char": "B", "int8": "b", "uint8": "B", "int16": "h",
    "uint16": "H", "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f",
    "float64": "d",
}
_DTYPES = {
    "bool": "?", "byte": "u1", "char": "u1", "int8": "i1", "uint8": "u1", "int16": "i2",
    "uint16": "u2", "int32": "i4", "uint32": "u4", "int64": "i8", "uint64": "u8",
    "float32": "f4", "float64": "f8",
}

# the steps of a plan; offsets are relative to the position the last ALIGN/STRING/... left
ALIGN, READ, READ_ARRAY, STRING, STRINGS, SEQUENCE, REPEAT, END = range(8)


class _Unserved(Exception):
    """A path the planner does not read from bytes (the caller decodes whole messages)."""


class _Planner:
    """Turns a message type and wanted paths into a list of steps (see :func:`field_reader`).

    ``offset`` is how far past the run-time position the walk is, known while only fixed-size
    fields were passed; ``aligned`` is what the run-time position is known to be a multiple of.
    """

    def __init__(self, fielddefs: dict, aligned: int = 8) -> None:
        self.fielddefs = fielddefs
        self.steps: list[tuple] = []
        self.offset = 0
        self.aligned = aligned  # 8 at the start of the message

    def align(self, size: int) -> None:
        if size <= self.aligned:
            self.offset = (self.offset + size - 1) & -size
        else:
            self.steps.append((ALIGN, self.offset, size))
            self.offset, self.aligned = 0, size

    def message(self, typename: str, wanted: dict[tuple, int]) -> None:
        """The steps of one message; ``wanted`` maps the paths (step tuples) read in it to
        their slots."""
        for name, desc in self.fielddefs[typename][1]:
            inner = {path[1:]: slot for path, slot in wanted.items() if path[0] == name}
            self.field(desc, inner)

    def field(self, desc: tuple, wanted: dict[tuple, int]) -> None:
        kind, rest = desc
        if kind == Nodetype.NAME:
            if () in wanted:
                raise _Unserved("a whole sub-message")
            self.message(rest, wanted)
        elif kind == Nodetype.BASE:
            if wanted.keys() - {()}:
                raise _Unserved("a path into a primitive")
            self.primitive(rest[0], wanted.get(()))
        else:
            element, length = rest
            self.array(kind, element, length, wanted)

    def primitive(self, base: str, slot: int | None) -> None:
        if base == "string":
            self.string(slot)
            return
        if base not in _SIZES:
            raise _Unserved(f"type {base}")
        size = _SIZES[base]
        self.align(size)
        if slot is not None:
            self.steps.append((READ, self.offset, _unpacker(base), slot))
        self.offset += size

    def string(self, slot: int | None) -> None:
        self.align(4)
        self.steps.append((STRING, self.offset, slot))
        self.offset, self.aligned = 0, 1

    def array(self, kind: int, element: tuple, length: int, wanted: dict[tuple, int]) -> None:
        whole = wanted.get(())
        indexes = {path[0]: slot for path, slot in wanted.items() if path and
                   isinstance(path[0], int) and len(path) == 1}
        if len(indexes) + (whole is not None) != len(wanted):
            raise _Unserved("a path into an array element")
        base = element[1][0] if element[0] == Nodetype.BASE else None
        if base is None or base not in _SIZES and base != "string":
            if wanted:
                raise _Unserved("an array of messages")
            self.repeat(kind == Nodetype.SEQUENCE, length, element)
        elif base == "string":
            if indexes:
                raise _Unserved("an element of a string array")
            if kind == Nodetype.SEQUENCE:
                self.align(4)
            self.steps.append((STRINGS, self.offset, kind == Nodetype.SEQUENCE, length, whole))
            self.offset, self.aligned = 0, 1
        elif kind == Nodetype.ARRAY:
            size = _SIZES[base]
            self.align(size)
            if whole is not None:
                self.steps.append((READ_ARRAY, self.offset, _dtype(base), length, whole))
            for index, slot in indexes.items():
                if index >= length:
                    raise _Unserved("an index past the end of a fixed array")
                self.steps.append((READ, self.offset + index * size, _unpacker(base), slot))
            self.offset += length * size
        else:
            size = _SIZES[base]
            self.align(4)
            self.steps.append((SEQUENCE, self.offset, size, _dtype(base), whole,
                               tuple(indexes.items()), _unpacker(base)))
            self.offset, self.aligned = 0, min(size, 4)

    def repeat(self, sequence: bool, length: int, element: tuple) -> None:
        if sequence:
            self.align(4)
        inner = _Planner(self.fielddefs, aligned=1)  # one element, wherever it starts
        inner.field(element, {})
        if inner.offset:
            inner.steps.append((ALIGN, inner.offset, 1))
        self.steps.append((REPEAT, self.offset, sequence, length, tuple(inner.steps)))
        self.offset, self.aligned = 0, 1


def _unpacker(base: str) -> Callable[[Any, int], tuple]:
    return struct.Struct("<" + _FORMATS[base]).unpack_from


def _dtype(base: str) -> np.dtype:
    return np.dtype("<" + _DTYPES[base])


_U32 = struct.Struct("<I").unpack_from


def _walk(steps: Sequence[tuple], body: memoryview, pos: int, values: list,
          max_sequence: int) -> int:
    """Run ``steps`` on ``body`` (the CDR after its header) from ``pos``; the position after."""
    for step in steps:
        kind = step[0]
        if kind == READ:
            values[step[3]] = step[2](body, pos + step[1])[0]
        elif kind == ALIGN:
            size = step[2]
            pos = (pos + step[1] + size - 1) & -size
        elif kind == STRING:
            text, pos = _string(body, pos + step[1])
            if step[2] is not None:
                values[step[2]] = text
        elif kind == SEQUENCE:
            pos += step[1]
            (count,) = _U32(body, pos)
            size = step[2]
            pos += 4
            if count > max_sequence or pos + count * size > len(body):
                raise MalformedMessage(f"invalid sequence length {count} at offset {pos}")
            if count and size > 4:
                pos = (pos + size - 1) & -size
            if step[4] is not None:
                values[step[4]] = np.frombuffer(body, step[3], count, pos).tolist()
            for index, slot in step[5]:
                values[slot] = step[6](body, pos + index * size)[0] if index < count else MISSING
            pos += count * size
        elif kind == READ_ARRAY:
            values[step[4]] = np.frombuffer(body, step[2], step[3], pos + step[1]).tolist()
        elif kind == STRINGS:
            pos += step[1]
            count = step[3]
            if step[2]:
                (count,) = _U32(body, pos)
                pos += 4
                if count > max_sequence or pos + count * 5 > len(body):
                    raise MalformedMessage(f"invalid sequence length {count} at offset {pos}")
            texts = []
            for _ in range(count):
                text, pos = _string(body, (pos + 3) & -4)
                texts.append(text)
            if step[4] is not None:
                values[step[4]] = texts
        elif kind == REPEAT:
            pos += step[1]
            count = step[3]
            if step[2]:
                (count,) = _U32(body, pos)
                pos += 4
                if count > max_sequence or pos + count > len(body):
                    raise MalformedMessage(f"invalid sequence length {count} at offset {pos}")
            for _ in range(count):
                pos = _walk(step[4], body, pos, values, max_sequence)
    return pos


def _string(body: memoryview, pos: int) -> tuple[str, int]:
    """The string at ``pos`` and the position after it, checked as rosbags checks it (its
    length, its terminator, UTF-8)."""
    (size,) = _U32(body, pos)
    end = pos + 4 + size
    if size < 1 or end > len(body) or body[end - 1] != 0:
        raise MalformedMessage(f"invalid string of length {size} at offset {pos}")
    try:
        return bytes(body[pos + 4:end - 1]).decode(), end
    except UnicodeDecodeError as exc:
        raise MalformedMessage(f"a string at offset {pos} is not UTF-8: {exc}") from None


def field_reader(
    store: TypeStore, typename: str, paths: Sequence[str | FieldPath]
) -> Callable[[bytes | memoryview], list[Any]]:
    """A function from a message's CDR bytes (with their 4-byte header) to the values of
    ``paths`` in it, in order (:data:`MISSING` for an element past the end of its sequence),
    as :func:`rasm.ros2.read_field` reads them from the decoded message.

    It raises :class:`MalformedMessage` for bytes that are not a message of this type. When
    :func:`serves` the paths, it reads them from the bytes; otherwise (and for big-endian CDR,
    which ROS 2 does not send) it decodes the whole message and reads them from that. A path
    the type does not have raises :class:`FieldPathError` now.
    """
    typename = store.resolve(typename)
    parsed = [FieldPath.parse(str(p)) for p in paths]
    for path in parsed:
        field_type(store, typename, path)  # FieldPathError for a path the type does not have
    whole = _whole_reader(store, typename, parsed)
    steps = _plan(store, typename, parsed)
    if steps is None:
        return whole
    steps, tail = steps
    count = len(parsed)
    max_sequence = store.rosbags.max_sequence_length

    def read(data: bytes | memoryview) -> list[Any]:
        if len(data) < 4 or data[0] != 0 or data[1] != 1:
            return whole(data)  # big endian, or no CDR at all: the decoder judges
        body = memoryview(data)[4:]
        values: list[Any] = [None] * count
        try:
            end = _walk(steps, body, 0, values, max_sequence) + tail
        except (MalformedMessage, struct.error, ValueError, IndexError) as exc:
            raise MalformedMessage(f"not a valid {typename}: {exc}") from None
        if end > len(body) or end + 3 < len(body):
            raise MalformedMessage(
                f"not a valid {typename}: {len(body)} bytes of CDR, the message takes {end}"
            )
        return values

    return read


def serves(store: TypeStore, typename: str, paths: Sequence[str | FieldPath]) -> bool:
    """Whether :func:`field_reader` reads these paths from the bytes, not decoding whole
    messages."""
    parsed = [FieldPath.parse(str(p)) for p in paths]
    return _plan(store, store.resolve(typename), parsed) is not None


def _plan(
    store: TypeStore, typename: str, paths: list[FieldPath]
) -> tuple[tuple[tuple, ...], int] | None:
    """The steps reading ``paths`` and the size after the last one, or None if not served."""
    wanted = {path.steps: slot for slot, path in enumerate(paths)}
    if len(wanted) != len(paths):
        return None  # a path twice: the whole message serves
    planner = _Planner(store.rosbags.fielddefs)
    try:
        planner.message(typename, wanted)
    except _Unserved:
        return None
    return tuple(planner.steps), planner.offset


def _whole_reader(store: TypeStore, typename: str, paths: list[FieldPath]):
    codec = store.codec(typename)

    def read(data: bytes | memoryview) -> list[Any]:
        message = codec.decode(data)
        out = []
        for path in paths:
            value: Any = message
            for step in path.steps:
                if isinstance(step, int) and step >= len(value):
                    value = MISSING
                    break
                value = value[step]
            out.append(value)
        return out

    return read


def projection(
    store: TypeStore, typename: str, paths: Sequence[str | FieldPath]
) -> Callable[[bytes | memoryview], dict[str, Any]]:
    """A function from a message's CDR bytes to a dict holding only what ``paths`` need, nested
    as the whole decoded message is: :func:`rasm.ros2.read_field` reads each of ``paths`` from
    it as from the whole message. An indexed path (``ranges[3]``) takes its whole array, a
    path into an array of messages the whole array. Raises :class:`MalformedMessage` as
    :func:`field_reader`'s function does."""
    kept: list[tuple[str, ...]] = []
    for path in sorted({_names_before_index(p) for p in paths}, key=len):
        if not any(path[:len(k)] == k for k in kept):  # a sub-message taken whole has it
            kept.append(path)
    read = field_reader(store, typename, [".".join(p) for p in kept])

    def project(data: bytes | memoryview) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for path, value in zip(kept, read(data), strict=True):
            inner = out
            for name in path[:-1]:
                inner = inner.setdefault(name, {})
            inner[path[-1]] = value
        return out

    return project


def _names_before_index(path: str | FieldPath) -> tuple[str, ...]:
    names = []
    for step in FieldPath.parse(str(path)).steps:
        if isinstance(step, int):
            break
        names.append(step)
    return tuple(names)
