"""The type store: ROS 2's standard interfaces plus an application's own ``.msg``, ``.srv`` and
``.action`` files.

The standard messages (std_msgs, geometry_msgs, sensor_msgs, nav_msgs, diagnostic_msgs, ...)
come from rosbags' bundled store of a ROS 2 distribution (Jazzy unless told otherwise), so no
ROS install is needed; rasm adds std_srvs and action_msgs' CancelGoal, which rosbags lacks.
Type names are ROS 2's ``pkg/msg/Name``; ``pkg/Name`` is accepted too. Each type has its
RIHS01 hash (what rmw_zenoh puts in key expressions and ROS 2 compares between endpoints) and
its DDS name ``pkg::msg::dds_::Name_``.

A service ``pkg/srv/Name`` is the messages ``pkg/srv/Name_Request``, ``_Response`` and
``_Event`` and the service's own description ``pkg/srv/Name`` (fields ``request_message``,
``response_message``, ``event_message``), whose RIHS01 hash is the service's, as ROS 2
computes it. An action ``pkg/action/Name`` is ``_Goal``, ``_Result``, ``_Feedback``, the
services ``_SendGoal`` and ``_GetResult``, ``_FeedbackMessage`` and its description.

Two things rosbags' parser drops are kept here: field defaults (``int32 x 5``; ROS sets an
unset field to its default, :meth:`TypeStore.defaults`) and ``wstring`` fields. A wstring is
stored as a nested message of one ``uint16[]`` (:data:`WSTRING_TYPE`, the same CDR: a length in
UTF-16 code units, then the units), shown to users as a str and hashed as ROS hashes a wstring.
"""

from __future__ import annotations

import ast
import json
import re
from collections.abc import Iterable
from functools import cache
from hashlib import sha256
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from rasm.errors import Location, SourceError
from rasm.ros2.errors import UnknownTypeError
from rasm.ros2.names import (
    NAME_PART,
    PLACEHOLDER_FIELD,
    WSTRING_TYPE,
    FieldType,
    dds_type_name,
    normalize_type,
    ros_type_name,
)

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

    from rasm.ros2.codec import MessageCodec

__all__ = [
    "DEFAULT_DISTRO",
    "DISTROS",
    "FieldType",
    "TypeStore",
    "WSTRING_TYPE",
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

_WSTRING_DEFS = {
    WSTRING_TYPE: ([], [("data", (Nodetype.SEQUENCE, ((Nodetype.BASE, ("uint16", 0)), 0)))])
}
# ROS 2's type_description_interfaces/FieldType ids, for the RIHS01 hash
_TYPE_IDS = {
    "int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
    "uint64": 9, "float32": 10, "float64": 11, "float128": 12, "char": 13, "bool": 15,
    "byte": 16, "string": 17, "wstring": 18, "bounded_string": 21, "bounded_wstring": 22,
}
_NESTED_TYPE_ID = 1
_SERVICE_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"

# standard interfaces that rosbags' bundled stores lack: (type name, definition)
_EXTRA_INTERFACES = (
    ("std_srvs/srv/Empty", "---\n"),
    ("std_srvs/srv/SetBool", "bool data\n---\nbool success\nstring message\n"),
    ("std_srvs/srv/Trigger", "---\nbool success\nstring message\n"),
    ("action_msgs/srv/CancelGoal", (
        "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\n"
        "int8 ERROR_GOAL_TERMINATED=3\naction_msgs/GoalInfo goal_info\n---\n"
        "int8 return_code\naction_msgs/GoalInfo[] goals_canceling\n"
    )),
)


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
        self._defaults: dict[str, dict[str, Any]] = {}  # type -> field -> its .msg default
        self._wstring_bounds: dict[str, dict[str, int]] = {}  # type -> wstring field -> bound
        self._store.register(_WSTRING_DEFS)
        if _SERVICE_EVENT_INFO in self._store.fielddefs:
            # rosbags' stores hold client_gid as char[16]; ROS 2's is uint8[16] (the same
            # bytes, another type hash, and every service's hash depends on it)
            consts, fields = self._store.fielddefs[_SERVICE_EVENT_INFO]
            self._store.fielddefs[_SERVICE_EVENT_INFO] = (consts, [
                (f, (Nodetype.ARRAY, ((Nodetype.BASE, ("uint8", 0)), 16)))
                if f == "client_gid" else (f, d) for f, d in fields
            ])
            self._store.cache.clear()
        if distro != "empty":
            for typename, text in _EXTRA_INTERFACES:
                self.register(self._definitions(typename, text, None))

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
        bounds = self._wstring_bounds.get(typename, {})
        found = {}
        for field, desc in self._store.fielddefs[typename][1]:
            if field == PLACEHOLDER_FIELD:
                continue
            ftype = _field_type(desc)
            if ftype.base == WSTRING_TYPE:
                ftype = FieldType("wstring", False, ftype.array, ftype.length,
                                  bounds.get(field, 0))
            found[field] = ftype
        return found

    def defaults(self, name: str) -> dict[str, Any]:
        """The fields of a type that its definition gives a default value, with that value
        (what ROS sets an unset field to; the others are zero)."""
        return dict(self._defaults.get(self.resolve(name), {}))

    def type_hash(self, name: str) -> str:
        """The RIHS01 type hash of a type (``RIHS01_`` and 64 hex digits)."""
        typename = self.resolve(name)
        if typename not in self._hashes:
            self._hashes[typename] = self._rihs01(typename)
        return self._hashes[typename]

    def _rihs01(self, typename: str) -> str:
        """ROS 2's RIHS01 hash: the SHA-256 of the type description as compact JSON (the
        type, then every type it refers to, sorted by name), as rosbags' ``hash_rihs01``
        makes it, with wstring fields hashed as wstrings."""
        described: dict[str, dict] = {}

        def describe(name: str) -> dict:
            if name not in described:
                described[name] = {}  # a type may (indirectly) refer to itself
                bounds = self._wstring_bounds.get(name, {})
                fields = self._store.fielddefs[name][1] or [
                    (PLACEHOLDER_FIELD, (Nodetype.BASE, ("uint8", 0)))
                ]
                described[name].update(
                    type_name=name,
                    fields=[field_json(f, _field_type(d), bounds.get(f, 0)) for f, d in fields],
                )
            return described[name]

        def field_json(name: str, ftype: FieldType, wstring_bound: int) -> dict:
            nested = ""
            if ftype.base == WSTRING_TYPE:
                base, bound = "wstring", wstring_bound
            elif ftype.is_message:
                describe(ftype.base)
                base, bound, nested = "", 0, ftype.base
            else:
                base, bound = ftype.base, ftype.string_bound
            type_id = _TYPE_IDS[f"bounded_{base}" if bound else base] if base else _NESTED_TYPE_ID
            increment = {"fixed": 48, "sequence": 96 if ftype.length else 144}.get(
                ftype.array or "", 0
            )
            return {
                "name": name,
                "type": {
                    "type_id": type_id + increment,
                    "capacity": ftype.length if ftype.array else 0,
                    "string_capacity": bound,
                    "nested_type_name": nested,
                },
            }

        description = {
            "type_description": describe(typename),
            "referenced_type_descriptions": [
                d for name, d in sorted(described.items()) if name != typename
            ],
        }
        return "RIHS01_" + sha256(json.dumps(description).encode()).hexdigest()

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

    def add_interface_dir(self, folder: str | Path, package: str) -> list[str]:
        """Add the ``msg/*.msg``, ``srv/*.srv`` and ``action/*.action`` files under ``folder``
        (a ROS package's layout) as ``package``'s; returns the new type names."""
        root = Path(folder)
        files = [
            path for kind in ("msg", "srv", "action")
            for path in sorted((root / kind).glob(f"*.{kind}"))
        ]
        return self.add_msg_files(files, package)

    def add_msg_files(self, paths: Iterable[str | Path], package: str) -> list[str]:
        """Add ``.msg``, ``.srv`` and ``.action`` files (by their suffix) as ``package/msg/<file
        stem>`` (``srv``, ``action``); returns the new type names.

        A file that does not parse, or that names a type the store does not hold, raises
        :class:`SourceError` with its file, line and column. Files may refer to each other.
        """
        files = [Path(p) for p in paths]
        if not re.fullmatch(NAME_PART, package or ""):
            where = Location(str(files[0])) if files else Location(str(package))
            raise SourceError(f"{package!r} is not a valid ROS package name", where)
        found: dict[str, tuple] = {}
        texts: dict[str, tuple[Path, str]] = {}
        for path in files:
            kind = path.suffix.lstrip(".")
            if kind not in ("msg", "srv", "action"):
                raise SourceError(
                    "not a ROS 2 interface file (.msg, .srv or .action)", Location(str(path))
                )
            typename = f"{package}/{kind}/{path.stem}"
            try:
                text = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise SourceError(
                    f"cannot read the interface definition: {exc}", Location(str(path))
                ) from None
            if not re.fullmatch(NAME_PART, path.stem):
                raise SourceError(
                    f"{path.stem!r} is not a valid interface name (letters, digits and '_', "
                    "starting with a letter)",
                    Location(str(path)),
                )
            made = self._definitions(typename, text, path)
            found.update(made)
            for name in made:
                texts[name] = (path, text)
        self._check_references(found, texts)
        try:
            self.register(found)
        except TypesysError as exc:
            path, _ = next(iter(texts.values()))
            raise SourceError(str(exc), Location(str(path))) from None
        return sorted(found)

    def _definitions(self, typename: str, text: str, path: Path | None) -> dict[str, tuple]:
        """rosbags definitions of one interface file's text (a message, or every message of a
        service or action); defaults and wstring bounds are noted on this store."""
        package, kind, name = typename.split("/")
        parts = _split_sections(text)
        expected = {"msg": 1, "srv": 2, "action": 3}[kind]
        if len(parts) != expected:
            where = Location(str(path)) if path else Location(typename)
            raise SourceError(
                f"a .{kind} file has {expected} section{'s' if expected > 1 else ''} separated "
                f"by lines of ---, this one has {len(parts)}", where,
            )
        base = f"{package}/{kind}/{name}"
        names = {
            "msg": [base],
            "srv": [f"{base}_Request", f"{base}_Response"],
            "action": [f"{base}_Goal", f"{base}_Result", f"{base}_Feedback"],
        }[kind]
        found: dict[str, tuple] = {}
        for part_name, (first_line, part) in zip(names, parts, strict=True):
            found.update(self._message_definition(part_name, part, path, text, first_line))
        if kind == "srv":
            found.update(_service_definitions(base))
        elif kind == "action":
            found.update(_action_definitions(base))
        return found

    def _message_definition(
        self, typename: str, text: str, path: Path | None, whole: str, first_line: int
    ) -> dict[str, tuple]:
        fields, defaults, bounds = _read_fields(text)
        package, _, short = typename.split("/")
        parsed_as = f"{package}/msg/{short}"  # rosbags' parser takes message names only
        try:
            found = get_types_from_msg(_without_wstring_bounds(text), parsed_as)
        except TypesysError as exc:
            raise SourceError(
                f"not a valid message definition: {_first_line(exc)}",
                _parse_location(path, whole) if path else Location(typename),
            ) from None
        consts, defs = found.pop(parsed_as)
        defs = [(field, _wstring_desc(desc, package)) for field, desc in defs]
        found[typename] = (consts, defs)
        types = {field: _field_type(desc) for field, desc in defs}
        checked: dict[str, Any] = {}
        for field, raw in defaults.items():
            ftype = types.get(field)
            if ftype is not None and ftype.base == WSTRING_TYPE:
                ftype = FieldType("wstring", False, ftype.array, ftype.length)
            if ftype is None or ftype.is_message:
                continue
            try:
                checked[field] = _default_value(raw, ftype)
            except ValueError as exc:
                line = first_line + fields[field] - 1
                where = Location(str(path), line, 1) if path else Location(typename)
                raise SourceError(f"field {field!r}: bad default {raw!r}: {exc}", where) from None
        self._defaults[typename] = checked
        self._wstring_bounds[typename] = bounds
        return found

    def register(self, definitions: dict[str, tuple]) -> None:
        """Add types given as rosbags definitions (what ``get_types_from_msg`` returns; a field
        of the type ``pkg/msg/wstring`` is a wstring)."""
        definitions = {
            name: (consts, [(f, _wstring_desc(d, name.split("/")[0])) for f, d in fields])
            for name, (consts, fields) in definitions.items()
        }
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


def _split_sections(text: str) -> list[tuple[int, str]]:
    """The sections of an interface file (split at lines of ``---``), each with the number of
    its first line."""
    sections: list[tuple[int, str]] = [(1, "")]
    for number, line in enumerate(text.splitlines(keepends=True), 1):
        if line.split("#", 1)[0].strip() == "---":
            sections.append((number + 1, ""))
        else:
            first, body = sections[-1]
            sections[-1] = (first, body + line)
    return sections


_FIELD_LINE = re.compile(
    r"\s*(?P<type>[A-Za-z][\w/]*)(?:<=(?P<bound>\d+))?(?:\[(?:<=)?\d*\])?\s+"
    r"(?P<name>[A-Za-z]\w*)(?:\s+(?P<default>\S.*?))?\s*"
)


def _read_fields(text: str) -> tuple[dict[str, int], dict[str, str], dict[str, int]]:
    """What rosbags' parser drops: each field's line (from 1), the default values as written,
    and the bounds of wstring fields."""
    lines: dict[str, int] = {}
    defaults: dict[str, str] = {}
    bounds: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), 1):
        code = _strip_comment(line)
        match = _FIELD_LINE.fullmatch(code)
        if match is None or "=" in code.split(match["name"], 1)[1][:1]:
            continue  # a constant (NAME=VALUE), a blank or something rosbags will refuse
        lines[match["name"]] = number
        if match["default"] is not None:
            defaults[match["name"]] = match["default"]
        if match["type"] == "wstring":
            bounds[match["name"]] = int(match["bound"] or 0)
    return lines, defaults, bounds


def _strip_comment(line: str) -> str:
    """A line without its comment; a ``#`` inside a quoted default is kept."""
    quote = ""
    for i, char in enumerate(line):
        if quote:
            if char == quote and line[i - 1] != "\\":
                quote = ""
        elif char in "\"'":
            quote = char
        elif char == "#":
            return line[:i]
    return line


def _without_wstring_bounds(text: str) -> str:
    """rosbags' parser reads ``wstring`` as a nested type and refuses ``wstring<=N``."""
    return re.sub(r"(?m)^(\s*)wstring<=\d+", r"\1wstring", text)


def _wstring_desc(desc: tuple, package: str) -> tuple:
    """A field's rosbags description with a ``wstring`` (read as a nested type of the
    package) made :data:`WSTRING_TYPE`."""
    kind, rest = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return (kind, (_wstring_desc(rest[0], package), rest[1]))
    if kind == Nodetype.NAME and rest.endswith("/msg/wstring"):
        return (kind, WSTRING_TYPE)
    return desc


_TOKEN = re.compile(r"""\s*("(?:\\.|[^"\\])*"|'(?:\\.|[^'\\])*'|[^,\s][^,]*?)\s*(?:,|$)""")


def _default_value(raw: str, ftype: FieldType) -> Any:
    """A default as written in a definition (``5``, ``"hi"``, ``[1, 2]``, ``true``) as the
    value of a field of ``ftype``; ValueError says why it is not one."""
    if ftype.array:
        inner = raw.strip()
        if not (inner.startswith("[") and inner.endswith("]")):
            raise ValueError("an array's default is written [a, b, ...]")
        inner = inner[1:-1].strip()
        items = [m[1] for m in _TOKEN.finditer(inner)] if inner else []
        if ftype.array == "fixed" and len(items) != ftype.length:
            raise ValueError(f"{ftype.length} values expected, {len(items)} given")
        if ftype.array == "sequence" and ftype.length and len(items) > ftype.length:
            raise ValueError(f"at most {ftype.length} values expected, {len(items)} given")
        return [_scalar(item, ftype.base) for item in items]
    return _scalar(raw.strip(), ftype.base)


def _scalar(text: str, base: str) -> Any:
    if base in ("string", "wstring"):
        if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
            return ast.literal_eval(text)
        return text
    if base == "bool":
        lowered = text.lower()
        if lowered in ("true", "1"):
            return True
        if lowered in ("false", "0"):
            return False
        raise ValueError("a bool is true or false")
    if base in ("float32", "float64"):
        return float(text)
    return int(text, 0)


def _service_definitions(base: str) -> dict[str, tuple]:
    """The event message and the description of service ``base`` (``pkg/srv/Name``), whose
    request and response are ``base_Request`` and ``base_Response``."""
    def name(target: str) -> tuple:
        return (Nodetype.NAME, target)

    def bounded(target: str) -> tuple:
        return (Nodetype.SEQUENCE, (name(target), 1))

    return {
        f"{base}_Event": ([], [
            ("info", name("service_msgs/msg/ServiceEventInfo")),
            ("request", bounded(f"{base}_Request")),
            ("response", bounded(f"{base}_Response")),
        ]),
        base: ([], [
            ("request_message", name(f"{base}_Request")),
            ("response_message", name(f"{base}_Response")),
            ("event_message", name(f"{base}_Event")),
        ]),
    }


def _action_definitions(base: str) -> dict[str, tuple]:
    """The services, feedback message and description of action ``base``
    (``pkg/action/Name``), whose goal, result and feedback are already defined."""
    def name(target: str) -> tuple:
        return (Nodetype.NAME, target)

    uuid = ("goal_id", name("unique_identifier_msgs/msg/UUID"))
    found: dict[str, tuple] = {
        f"{base}_SendGoal_Request": ([], [uuid, ("goal", name(f"{base}_Goal"))]),
        f"{base}_SendGoal_Response": ([], [
            ("accepted", (Nodetype.BASE, ("bool", 0))),
            ("stamp", name("builtin_interfaces/msg/Time")),
        ]),
        f"{base}_GetResult_Request": ([], [uuid]),
        f"{base}_GetResult_Response": ([], [
            ("status", (Nodetype.BASE, ("int8", 0))),
            ("result", name(f"{base}_Result")),
        ]),
        f"{base}_FeedbackMessage": ([], [uuid, ("feedback", name(f"{base}_Feedback"))]),
    }
    found.update(_service_definitions(f"{base}_SendGoal"))
    found.update(_service_definitions(f"{base}_GetResult"))
    found[base] = ([], [
        ("goal", name(f"{base}_Goal")),
        ("result", name(f"{base}_Result")),
        ("feedback", name(f"{base}_Feedback")),
        ("send_goal_service", name(f"{base}_SendGoal")),
        ("get_result_service", name(f"{base}_GetResult")),
        ("feedback_message", name(f"{base}_FeedbackMessage")),
    ])
    return found


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
