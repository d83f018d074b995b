"""The type store: ROS 2's standard interfaces plus an application's own ``.msg`` files.

The standard interfaces (std_msgs, geometry_msgs, sensor_msgs, nav_msgs, diagnostic_msgs, ...)
come from rosbags' bundled store of a ROS 2 distribution (Jazzy unless told otherwise), so no
ROS install is needed. Type names are ROS 2's ``pkg/msg/Name``; ``pkg/Name`` is accepted too.
Each type has its RIHS01 hash (what rmw_zenoh puts in key expressions and ROS 2 compares
between endpoints) and its DDS name ``pkg::msg::dds_::Name_``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from rasm.errors import Location, SourceError
from rasm.ros2.errors import UnknownTypeError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

    from rasm.ros2.codec import MessageCodec

__all__ = [
    "DEFAULT_DISTRO",
    "DISTROS",
    "FieldType",
    "TypeStore",
    "dds_type_name",
    "normalize_type",
    "ros_type_name",
]

DISTROS = {
    "humble": Stores.ROS2_HUMBLE,
    "iron": Stores.ROS2_IRON,
    "jazzy": Stores.ROS2_JAZZY,
    "kilted": Stores.ROS2_KILTED,
    "lyrical": Stores.ROS2_LYRICAL,
}
DEFAULT_DISTRO = "jazzy"  # the current long-term-support release
_STORES = {**DISTROS, "empty": Stores.EMPTY}  # "empty": only what is added (a bag's own types)

# ROS 2 requires an empty message to carry this one byte; rasm hides it from users.
PLACEHOLDER_FIELD = "structure_needs_at_least_one_member"

_PART = r"[A-Za-z][A-Za-z0-9_]*"
_TYPE_NAME = re.compile(rf"({_PART})/(?:(msg)/)?({_PART})")
_DDS_NAME = re.compile(rf"({_PART})::(msg)::dds_::({_PART})_")


def normalize_type(name: str) -> str:
    """``pkg/msg/Name`` for ``pkg/msg/Name`` or ``pkg/Name``; :class:`UnknownTypeError` else."""
    match = _TYPE_NAME.fullmatch(name) if isinstance(name, str) else None
    if match is None:
        raise UnknownTypeError(
            f"{name!r} is not a ROS 2 message type name (write it as pkg/msg/Name, e.g. "
            "nav_msgs/msg/Odometry)"
        )
    return f"{match[1]}/msg/{match[3]}"


def dds_type_name(name: str) -> str:
    """The DDS (and rmw_zenoh) name of a message type: ``std_msgs::msg::dds_::String_``."""
    package, _, short = normalize_type(name).split("/")
    return f"{package}::msg::dds_::{short}_"


def ros_type_name(dds_name: str) -> str | None:
    """``pkg/msg/Name`` for a DDS type name ``pkg::msg::dds_::Name_``, else None."""
    match = _DDS_NAME.fullmatch(dds_name)
    return f"{match[1]}/msg/{match[3]}" if match else None


@dataclass(frozen=True)
class FieldType:
    """The type of one message field, as ROS writes it (``float64[36]``, ``float32[]``, ...).

    ``base`` is a primitive (``float64``, ``string``, ...) or a message type name;
    ``array`` is ``None``, ``"fixed"`` (``length`` elements) or ``"sequence"`` (at most
    ``length`` elements, 0 meaning unbounded); ``string_bound`` limits a string's length.
    """

    base: str
    is_message: bool = False
    array: str | None = None
    length: int = 0
    string_bound: int = 0

    @property
    def element(self) -> FieldType:
        """The type of one element (the field itself when it is not an array)."""
        return FieldType(self.base, self.is_message, None, 0, self.string_bound)

    def __str__(self) -> str:
        text = self.base + (f"<={self.string_bound}" if self.string_bound else "")
        if self.array == "fixed":
            return f"{text}[{self.length}]"
        if self.array == "sequence":
            return f"{text}[<={self.length}]" if self.length else f"{text}[]"
        return text


def _field_type(desc: tuple) -> FieldType:
    kind, rest = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        element, length = rest
        inner = _field_type(element)
        array = "fixed" if kind == Nodetype.ARRAY else "sequence"
        return FieldType(inner.base, inner.is_message, array, length, inner.string_bound)
    if kind == Nodetype.NAME:
        return FieldType(rest, is_message=True)
    base, bound = rest
    return FieldType(base, string_bound=bound if base == "string" else 0)


class TypeStore:
    """The message types rasm can encode and decode.

    ``distro`` picks the bundled standard interfaces (``jazzy``, ``humble``, ``kilted``, ...;
    ``empty`` for none). :meth:`add_msg_dir` and :meth:`add_msg_files` add an application's own
    types.
    """

    def __init__(self, distro: str = DEFAULT_DISTRO) -> None:
        if distro not in _STORES:
            raise UnknownTypeError(
                f"unknown ROS 2 distribution {distro!r}; known: {', '.join(sorted(DISTROS))}"
            )
        self.distro = distro
        self._store: Typestore = get_typestore(_STORES[distro])
        self._codecs: dict[str, MessageCodec] = {}
        self._hashes: dict[str, str] = {}

    # -- queries --------------------------------------------------------------------------------
    def __contains__(self, name: object) -> bool:
        try:
            return normalize_type(name) in self._store.fielddefs  # type: ignore[arg-type]
        except UnknownTypeError:
            return False

    @property
    def types(self) -> list[str]:
        """Every type name the store holds, sorted."""
        return sorted(self._store.fielddefs)

    def resolve(self, name: str) -> str:
        """The normalized name of a type the store holds; :class:`UnknownTypeError` otherwise."""
        typename = normalize_type(name)
        if typename not in self._store.fielddefs:
            package = typename.split("/")[0]
            known = sorted(t for t in self._store.fielddefs if t.startswith(package + "/"))
            hint = (
                f"; {package} has {', '.join(known[:8])}{', ...' if len(known) > 8 else ''}"
                if known
                else f"; no package {package!r} is known (add its .msg files to the app's msg/)"
            )
            raise UnknownTypeError(f"unknown message type {typename!r}{hint}")
        return typename

    def fields(self, name: str) -> dict[str, FieldType]:
        """The fields of a message type, in order, by their ROS names."""
        typename = self.resolve(name)
        return {
            field: _field_type(desc)
            for field, desc in self._store.fielddefs[typename][1]
            if field != PLACEHOLDER_FIELD
        }

    def type_hash(self, name: str) -> str:
        """The RIHS01 type hash of a message type (``RIHS01_`` and 64 hex digits)."""
        typename = self.resolve(name)
        if typename not in self._hashes:
            self._hashes[typename] = self._store.hash_rihs01(typename)
        return self._hashes[typename]

    def codec(self, name: str) -> MessageCodec:
        """The encoder/decoder of a message type (built once, then reused)."""
        typename = self.resolve(name)
        codec = self._codecs.get(typename)
        if codec is None:
            from rasm.ros2.codec import MessageCodec  # the codec module builds on this one

            codec = self._codecs[typename] = MessageCodec(self, typename)
        return codec

    @property
    def rosbags(self) -> Typestore:
        """rosbags' own store underneath (for rosbags' readers and writers)."""
        return self._store

    # -- an application's own types -------------------------------------------------------------
    def add_msg_dir(self, directory: str | Path, package: str | None = None) -> list[str]:
        """Add every ``*.msg`` file of ``directory``; returns the new type names.

        The package defaults to the name of the folder above ``msg/`` (ROS's ``pkg/msg/Name.msg``
        layout), else to the folder's own name.
        """
        folder = Path(directory)
        if not folder.is_dir():
            raise SourceError("no such folder of .msg files", Location(str(folder)))
        if package is None:
            package = folder.parent.name if folder.name == "msg" else folder.name
        return self.add_msg_files(sorted(folder.glob("*.msg")), package)

    def add_msg_files(self, paths: Iterable[str | Path], package: str) -> list[str]:
        """Add ``.msg`` files as ``package/msg/<file stem>``; returns the new type names.

        A file that does not parse, or that names a type the store does not hold, raises
        :class:`SourceError` with its file, line and column. Files may refer to each other.
        """
        files = [Path(p) for p in paths]
        if not re.fullmatch(_PART, package or ""):
            where = Location(str(files[0])) if files else Location(str(package))
            raise SourceError(f"{package!r} is not a valid ROS package name", where)
        found: dict[str, tuple] = {}
        texts: dict[str, tuple[Path, str]] = {}
        for path in files:
            typename = f"{package}/msg/{path.stem}"
            try:
                text = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise SourceError(
                    f"cannot read the message definition: {exc}", Location(str(path))
                ) from None
            if not re.fullmatch(_PART, path.stem):
                raise SourceError(
                    f"{path.stem!r} is not a valid message name (letters, digits and '_', "
                    "starting with a letter)",
                    Location(str(path)),
                )
            try:
                found.update(get_types_from_msg(text, typename))
            except TypesysError as exc:
                raise SourceError(
                    f"not a valid message definition: {_first_line(exc)}",
                    _parse_location(path, text),
                ) from None
            texts[typename] = (path, text)
        self._check_references(found, texts)
        try:
            self.register(found)
        except TypesysError as exc:
            path, _ = next(iter(texts.values()))
            raise SourceError(str(exc), Location(str(path))) from None
        return sorted(found)

    def register(self, definitions: dict[str, tuple]) -> None:
        """Add types given as rosbags definitions (what ``get_types_from_msg`` returns)."""
        self._store.register(definitions)
        self._codecs.clear()
        self._hashes.clear()

    def _check_references(
        self, found: dict[str, tuple], texts: dict[str, tuple[Path, str]]
    ) -> None:
        known = set(self._store.fielddefs) | set(found)
        for typename, (_, fields) in found.items():
            for field, desc in fields:
                ref = _field_type(desc)
                if ref.is_message and ref.base not in known:
                    path, text = texts[typename]
                    short = ref.base.rsplit("/", 1)[-1]
                    raise SourceError(
                        f"field {field!r} has the unknown type {ref.base!r} (neither a primitive, "
                        "a standard interface nor one of the app's .msg files)",
                        _word_location(path, text, short),
                    )


def _first_line(exc: Exception) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _parse_location(path: Path, text: str) -> Location:
    """Where a definition stops parsing: the first line that is neither a comment, blank, a
    field (``TYPE NAME [DEFAULT]``) nor a constant (``TYPE NAME=VALUE``)."""
    field = re.compile(r"\s*[A-Za-z][\w/]*(<=\d+)?(\[(<=)?\d*\])?\s+[A-Za-z]\w*(\s*=.*|\s+.*)?")
    for number, line in enumerate(text.splitlines(), 1):
        code = line.split("#", 1)[0]
        if code.strip() and not field.fullmatch(code):
            return Location(str(path), number, len(code) - len(code.lstrip()) + 1)
    return Location(str(path))


def _word_location(path: Path, text: str, word: str) -> Location:
    """The first place a type name is used as a field type in ``text``."""
    pattern = re.compile(rf"(?<![\w/])((?:\w+/)?{re.escape(word)})(<=\d+)?(\[[^\]]*\])?\s")
    for number, line in enumerate(text.splitlines(), 1):
        code = line.split("#", 1)[0]
        match = pattern.match(code.lstrip())
        if match:
            return Location(str(path), number, len(code) - len(code.lstrip()) + 1)
    return Location(str(path))


@cache
def default_store() -> TypeStore:
    """One shared store of the default distribution's standard interfaces (no app types)."""
    return TypeStore()
