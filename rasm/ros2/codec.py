"""CDR bytes <-> plain dicts for one message type.

A decoded message is a plain nested dict, as JSON would hold it: nested messages are dicts,
arrays and sequences are lists (never numpy arrays), ``byte`` and ``char`` are integers, time
stamps are ``{"sec": ..., "nanosec": ...}``. Floats keep what the sender sent, ``inf`` and
``nan`` included (a LaserScan marks "no echo" with ``inf``).

Encoding takes such a dict, possibly partial: a field that is not given takes its ``.msg``
default, else zero (``0``, ``0.0``, ``False``, ``""``, an empty sequence, a fixed array of
zeros), as in ROS. A ``wstring`` is a str (UTF-16 on the wire, its bound in UTF-16 units).
A value of the wrong kind, an integer out of its range, a fixed array of the wrong length or
an unknown field name raises :class:`MessageError` naming the field path and the type.

Both directions run rosbags' serializer (its CDR is byte-identical to ROS 2's) with converters
between its message objects and dicts, built once per type from the type's fields.
"""

from __future__ import annotations

import copy
import numbers
import struct
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.serde import SerdeError
from rosbags.typesys.base import normalize_fieldname

from rasm.ros2.errors import MalformedMessage, MessageError
from rasm.ros2.names import PLACEHOLDER_FIELD, WSTRING_TYPE, FieldType, dds_type_name

if TYPE_CHECKING:
    from rasm.ros2.types import TypeStore

__all__ = ["MessageCodec"]

_INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint8": (0, 2**8 - 1),
    "byte": (0, 2**8 - 1),
    "char": (0, 2**8 - 1),
    "uint16": (0, 2**16 - 1),
    "uint32": (0, 2**32 - 1),
    "uint64": (0, 2**64 - 1),
}
_FLOATS = {"float32", "float64"}
_FLOAT32 = struct.Struct("<f")
_FLOAT_MAX = {name: float(np.finfo(name).max) for name in _FLOATS}
_DTYPES = {
    "bool": np.bool_, "byte": np.int8, "char": np.uint8, "uint8": np.uint8, "int8": np.int8,
    "uint16": np.uint16, "int16": np.int16, "uint32": np.uint32, "int32": np.int32,
    "uint64": np.uint64, "int64": np.int64, "float32": np.float32, "float64": np.float64,
}
# what a malformed buffer makes rosbags' generated deserializers raise
_DECODE_ERRORS = (
    SerdeError, struct.error, ValueError, IndexError, TypeError, OverflowError, MemoryError,
    UnicodeDecodeError, KeyError,
)

Encoder = Callable[[Any, str], Any]


class _Invalid(Exception):
    """A value that does not fit its field; :class:`MessageCodec` names the message type."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(reason)
        self.path = path
        self.reason = reason


class MessageCodec:
    """Encode and decode one message type (get one from :meth:`TypeStore.codec`)."""

    def __init__(self, store: TypeStore, typename: str) -> None:
        self.typename = typename
        self.type_hash = store.type_hash(typename)
        self.dds_name = dds_type_name(typename)
        self._rosbags = store.rosbags
        self._to_dict = _dict_maker(store, typename, {})
        self._from_dict = _object_maker(store, typename, {})
        self._zero = _zero_maker(store, typename)

    def decode(self, data: bytes | memoryview) -> dict[str, Any]:
        """The message in ``data`` (CDR with its 4-byte header) as a dict.

        Raises :class:`MalformedMessage` for anything that is not a valid encoding of this type.
        """
        return self._to_dict(self.decode_object(data))

    def decode_object(self, data: bytes | memoryview) -> Any:
        """The message in ``data`` as rosbags' message object (attributes, numpy arrays), not
        converted to a dict: for reading a few fields of many messages, where the conversion
        of the rest would cost more than the decoding. :meth:`as_dict` converts one.

        Raises :class:`MalformedMessage` as :meth:`decode` does.
        """
        try:
            return self._rosbags.deserialize_cdr(data, self.typename)
        except _DECODE_ERRORS as exc:
            raise MalformedMessage(f"not a valid {self.typename}: {exc}") from None

    def as_dict(self, message: Any) -> dict[str, Any]:
        """A message object of this type (:meth:`decode_object`) as :meth:`decode`'s dict."""
        return self._to_dict(message)

    def encode(self, message: Mapping[str, Any]) -> bytes:
        """CDR bytes (little endian, with the header) of ``message``; unset fields take their
        default."""
        return bytes(self._rosbags.serialize_cdr(self._message_object(message), self.typename))

    def check(self, message: Mapping[str, Any]) -> None:
        """Raise :class:`MessageError` if :meth:`encode` would refuse ``message``."""
        self._message_object(message)

    def _message_object(self, message: Mapping[str, Any]) -> Any:
        try:
            return self._from_dict(message, "")
        except _Invalid as exc:
            where = f"field {exc.path!r} of {self.typename}" if exc.path else self.typename
            raise MessageError(f"{where}: {exc.reason}") from None

    def zero(self) -> dict[str, Any]:
        """A message with every field at its default (zero where the definition gives none),
        as a dict (a fresh one each call)."""
        return self._zero()

    def __repr__(self) -> str:
        return f"<MessageCodec {self.typename}>"


# -- objects to dicts ---------------------------------------------------------------------------
def _dict_maker(store: TypeStore, typename: str, made: dict) -> Callable[[Any], dict]:
    if typename in made:
        return made[typename]
    converters: list[tuple[str, str, Callable[[Any], Any] | None]] = []

    def to_dict(obj: Any) -> dict[str, Any]:
        out = {}
        for name, attribute, convert in converters:
            value = getattr(obj, attribute)
            out[name] = value if convert is None else convert(value)
        return out

    made[typename] = to_dict  # before the fields: a type may (indirectly) contain itself
    for name, ftype in store.fields(typename).items():
        converters.append((name, normalize_fieldname(name), _value_converter(store, ftype, made)))
    return to_dict


def _value_converter(store: TypeStore, ftype: FieldType, made: dict) -> Callable | None:
    if ftype.is_message:
        nested = _dict_maker(store, ftype.base, made)
        if ftype.array:
            return lambda values: [nested(v) for v in values]
        return nested
    if ftype.base == "wstring":
        return (lambda values: [_wstring_text(v) for v in values]) if ftype.array else _wstring_text
    if ftype.base == "byte":  # rosbags reads a byte as int8; ROS 2's byte is 0..255
        return _bytes_to_list if ftype.array else _unsigned_byte
    if ftype.array:
        if ftype.base == "string":
            return list
        return _to_list  # rosbags gives numpy arrays for primitive arrays and sequences
    return None


def _wstring_text(value: Any) -> str:
    return np.asarray(value.data, dtype="<u2").tobytes().decode("utf-16-le", "replace")


def _unsigned_byte(value: int) -> int:
    return value & 0xFF


def _bytes_to_list(values: Any) -> list:
    return np.asarray(values, dtype=np.int8).view(np.uint8).tolist()


def _to_list(values: Any) -> list:
    return values.tolist() if isinstance(values, np.ndarray) else list(values)


# -- dicts to objects ---------------------------------------------------------------------------
def _object_maker(store: TypeStore, typename: str, made: dict) -> Encoder:
    if typename in made:
        return made[typename]
    fields: dict[str, tuple[str, Encoder]] = {}
    message_class = store.rosbags.types[typename]
    placeholder = PLACEHOLDER_FIELD in dict(store.rosbags.fielddefs[typename][1])
    defaults = store.defaults(typename)

    def make(value: Any, path: str) -> Any:
        if value is None:
            value = {}
        elif not isinstance(value, Mapping):
            raise _Invalid(
                path,
                f"expected a {typename} (a dict of its fields), "
                f"got {_show(value)}"
            )
        for key in value:
            if key not in fields:
                known = ", ".join(fields) or "none"
                raise _Invalid(
                    _join(path, key),
                    f"{typename} has no field {key!r} "
                    f"(its fields: {known})"
                )
        kwargs = {
            attribute: encode(value[name] if name in value else defaults.get(name),
                              _join(path, name))
            for name, (attribute, encode) in fields.items()
        }
        if placeholder:
            kwargs[PLACEHOLDER_FIELD] = 0
        return message_class(**kwargs)

    made[typename] = make
    for name, ftype in store.fields(typename).items():
        fields[name] = (normalize_fieldname(name), _value_encoder(store, ftype, made))
    return make


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _show(value: Any) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{text} ({type(value).__name__})"


def _value_encoder(store: TypeStore, ftype: FieldType, made: dict) -> Encoder:
    element = _element_encoder(store, ftype, made)
    if not ftype.array:
        return element
    kind = str(ftype)
    dtype = None if ftype.is_message or ftype.base in ("string", "wstring") else _DTYPES[ftype.base]

    def encode_array(values: Any, path: str) -> Any:
        if values is None:
            values = [] if ftype.array == "sequence" else [None] * ftype.length
        elif isinstance(values, np.ndarray):
            values = values.tolist()
        elif isinstance(values, str | bytes | Mapping) or not hasattr(values, "__len__"):
            raise _Invalid(path, f"expected {kind} (a list), got {_show(values)}")
        if ftype.array == "fixed" and len(values) != ftype.length:
            raise _Invalid(
                path,
                f"expected {kind}, exactly {ftype.length} elements, "
                f"got {len(values)}"
            )
        if ftype.array == "sequence" and ftype.length and len(values) > ftype.length:
            raise _Invalid(
                path,
                f"expected {kind}, at most {ftype.length} elements, "
                f"got {len(values)}"
            )
        items = [element(v, f"{path}[{i}]") for i, v in enumerate(values)]
        return items if dtype is None else np.array(items, dtype=dtype)

    return encode_array


def _element_encoder(store: TypeStore, ftype: FieldType, made: dict) -> Encoder:
    base = ftype.base
    if ftype.is_message:
        return _object_maker(store, base, made)
    if base == "bool":
        def encode_bool(value: Any, path: str) -> bool:
            if value is None:
                return False
            if not isinstance(value, bool | np.bool_):
                raise _Invalid(path, f"expected bool, got {_show(value)}")
            return bool(value)
        return encode_bool
    if base in _FLOATS:
        single = base == "float32"

        def encode_float(value: Any, path: str) -> float:
            if value is None:
                return 0.0
            if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
                raise _Invalid(path, f"expected {base}, got {_show(value)}")
            try:
                number = float(value)
                if single:
                    _FLOAT32.pack(number)  # a finite value that rounds past float32's largest
            except OverflowError:
                raise _Invalid(
                    path, f"{_show(value)} is out of range for {base} (its largest finite "
                    f"value is {_FLOAT_MAX[base]!r})"
                ) from None
            return number
        return encode_float
    if base == "wstring":
        wstring_class = store.rosbags.types[WSTRING_TYPE]
        bound = ftype.string_bound

        def encode_wstring(value: Any, path: str) -> Any:
            if value is None:
                value = ""
            if not isinstance(value, str):
                raise _Invalid(path, f"expected wstring, got {_show(value)}")
            try:
                units = np.frombuffer(value.encode("utf-16-le"), dtype="<u2")
            except UnicodeEncodeError:
                raise _Invalid(path, f"{_show(value)} is not Unicode text") from None
            if bound and len(units) > bound:
                raise _Invalid(path, f"expected wstring<={bound}, got {len(units)} UTF-16 units")
            if 0 in units:
                raise _Invalid(path, "a ROS wstring cannot hold a NUL character")
            return wstring_class(data=units.astype(np.uint16))
        return encode_wstring
    if base == "string":
        bound = ftype.string_bound

        def encode_string(value: Any, path: str) -> str:
            if value is None:
                return ""
            if not isinstance(value, str):
                raise _Invalid(path, f"expected string, got {_show(value)}")
            if bound and len(value) > bound:
                raise _Invalid(
                    path,
                    f"expected string<={bound}, got {len(value)} characters"
                )
            try:
                value.encode("utf-8")
            except UnicodeEncodeError:
                raise _Invalid(
                    path,
                    f"{_show(value)} is not Unicode text"
                ) from None
            if "\x00" in value:
                raise _Invalid(path, "a ROS string cannot hold a NUL character")
            return value
        return encode_string
    low, high = _INT_RANGES[base]

    def encode_int(value: Any, path: str) -> int:
        if value is None:
            return 0
        if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
            raise _Invalid(path, f"expected {base}, got {_show(value)}")
        if not low <= value <= high:
            raise _Invalid(
                path,
                f"{value} is out of range for {base} ({low}..{high})"
            )
        if base == "byte" and value > 127:  # rosbags writes a byte as int8: the same octet
            return int(value) - 256
        return int(value)
    return encode_int


# -- zero messages ------------------------------------------------------------------------------
def _zero_maker(store: TypeStore, typename: str) -> Callable[[], dict]:
    parts: list[tuple[str, Callable[[], Any]]] = []
    defaults = store.defaults(typename)
    for name, ftype in store.fields(typename).items():
        if name in defaults:
            parts.append((name, lambda value=defaults[name]: copy.deepcopy(value)))
        else:
            parts.append((name, _zero_value(store, ftype)))
    return lambda: {name: make() for name, make in parts}


def _zero_value(store: TypeStore, ftype: FieldType) -> Callable[[], Any]:
    if ftype.array == "sequence":
        return list
    element = _zero_element(store, ftype)
    if ftype.array == "fixed":
        return lambda: [element() for _ in range(ftype.length)]
    return element


def _zero_element(store: TypeStore, ftype: FieldType) -> Callable[[], Any]:
    if ftype.is_message:
        return _zero_maker(store, ftype.base)
    if ftype.base == "bool":
        return lambda: False
    if ftype.base in _FLOATS:
        return lambda: 0.0
    if ftype.base in ("string", "wstring"):
        return str
    return int
