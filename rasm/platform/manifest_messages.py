"""The manifest's checks of messages: untyped topics carry JSON; a probe or effector with a ROS 2
interface type is checked against the app's type store (topic names, types, field paths and
the value types they give), each problem at its place in app.yaml."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rasm.errors import Location, RasmError, SourceError
from rasm.extras import missing_extra
from rasm.values import TYPES
from rasm.yamltext import YamlSource

if TYPE_CHECKING:
    from rasm.platform.manifest import Effector, ExternalVerdict, Probe, Signal

__all__ = ["check_messages"]

PAYLOAD_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def check_messages(
    src: YamlSource,
    folder: Path,
    probes: list[Probe],
    effectors: dict[str, Effector],
    external: dict[str, ExternalVerdict],
    problems: list[SourceError],
    base: Any = None,
) -> tuple[Any, dict[str, Effector]]:
    """Check what the manifest says about messages: untyped topics carry JSON, typed ones a
    ROS 2 interface whose field paths must exist and fit their signals. Returns the app's type
    store (None when nothing is typed) and the effectors, a ROS 2 one with the value types of
    its payload keys filled in from its message's fields."""
    typed = any(
        item.type for item in (*probes, *effectors.values(), *external.values())
    )
    for i, probe in enumerate(probes):
        if probe.type:
            continue
        written = src.data["probes"][i]
        for key, signal in probe.signals.items():
            if signal.field is not None:
                problems.append(src.error(
                    f"signal '{key}': a field path reads a ROS 2 message; give probe "
                    f"{probe.topic} its interface type (type: pkg/msg/Name)",
                    src.at(["probes", i, "signals", key, "field"]),
                ))
        for key in ("stamp", "qos", "publisher"):
            if key in written:
                problems.append(src.error(
                    f"probe {probe.topic}: {key} belongs to a ROS 2 topic; give the probe its "
                    "interface type (type: pkg/msg/Name)",
                    src.key(written, key),
                ))
    for name, effector in effectors.items():
        if effector.type:
            continue
        written = src.data["effectors"][name]
        for key, kind in (written.get("fields") or {}).items():
            if kind not in TYPES:
                problems.append(src.error(
                    f"effector {name}: field '{key}' has the type {kind!r}; a value type is "
                    f"one of {', '.join(TYPES)} (a ROS 2 effector, with a type, maps message "
                    "fields to payload keys instead)",
                    src.at(["effectors", name, "fields", key]),
                ))
        if "qos" in written:
            problems.append(src.error(
                f"effector {name}: qos belongs to a ROS 2 topic; give the effector its "
                "interface type (type: pkg/msg/Name)",
                src.key(written, "qos"),
            ))
    problems.extend(_external_problems(src, external))
    if problems or not typed:
        return None, effectors
    try:
        from rasm.platform.messages import app_type_store
        from rasm.ros2 import RosError
    except ModuleNotFoundError as exc:
        missing = missing_extra(exc, "a ROS 2 interface type")
        if missing is None:
            raise
        first = next(i for i, p in enumerate(probes) if p.type) if probes else None
        where = src.at(["probes", first, "type"]) if first is not None else src.start()
        problems.append(src.error(str(missing), where))
        return None, effectors
    try:
        store = app_type_store(folder, base)
    except SourceError as exc:
        problems.append(exc)
        return None, effectors
    except RosError as exc:
        problems.append(SourceError(str(exc), Location(str(folder / "msg"))))
        return None, effectors
    for i, probe in enumerate(probes):
        if probe.type:
            _check_probe(src, store, i, probe, problems)
    checked = dict(effectors)
    by_probe = {key: (p, signal) for p in probes for key, signal in p.signals.items()}
    for name, effector in effectors.items():
        if effector.type:
            checked[name] = _check_effector(src, store, effector, problems)
        for part in ("response", "feedback"):
            for key, signal in getattr(checked[name], part).items():
                probe, known = by_probe.get(key, (None, None))
                if known is not None and known.type != signal.type:
                    problems.append(src.error(
                        f"effector {name}: '{key}' is {signal.type} here but probe "
                        f"{probe.topic} gives it as {known.type}: one knowledge key has one type",
                        src.at(["effectors", name, part, signal.field]),
                    ))
    for name, verdict in external.items():
        if verdict.type:
            path = ["trustworthiness", "external_verdicts", name, "topic"]
            _check_topic(src, verdict.topic, path, problems)
    return store, checked


def _external_problems(src: YamlSource, external: dict[str, ExternalVerdict]) -> list[SourceError]:
    """A publisher is a ROS 2 node (a JSON source has none); an Empty source's violations last
    ``hold`` seconds and its silence is its "holds", so it has no freshness."""
    problems = []
    for name, verdict in external.items():
        written = src.data["trustworthiness"]["external_verdicts"][name]
        if not verdict.type and "publisher" in written:
            problems.append(src.error(
                f"external verdict {name}: publisher names a ROS 2 node; give the source its "
                "type (std_msgs/msg/Bool or std_msgs/msg/Empty), or sign its verdicts over "
                "MQTT with RASM_ACTION_KEY",
                src.key(written, "publisher"),
            ))
        if verdict.type == "std_msgs/msg/Empty" and "freshness" in written:
            problems.append(src.error(
                f"external verdict {name}: an Empty source has no freshness (each message is "
                "a violation that vetoes for hold seconds, and its silence is its \"holds\"); "
                "use hold",
                src.key(written, "freshness"),
            ))
    return problems


def _check_topic(
    src: YamlSource, topic: str, path: list[Any], problems: list[SourceError]
) -> bool:
    from rasm.ros2.transport import validate_ros_topic

    try:
        validate_ros_topic(topic)
    except RasmError as exc:
        problems.append(src.error(str(exc), src.at(path)))
        return False
    return True


def _resolve(
    src: YamlSource, store: Any, typename: str, path: list[Any], problems: list[SourceError]
) -> str | None:
    import difflib

    from rasm.ros2 import RosError

    try:
        return store.resolve(typename)
    except RosError as exc:
        message = str(exc)
        close = difflib.get_close_matches(typename, store.types, n=1)
        if close:
            message = f"unknown message type {typename!r}: did you mean {close[0]}?"
        problems.append(src.error(message, src.at(path), len(typename)))
        return None


def _check_probe(
    src: YamlSource, store: Any, i: int, probe: Probe, problems: list[SourceError]
) -> None:
    from rasm.platform.messages import takes, value_type
    from rasm.ros2 import RosError, field_type

    _check_topic(src, probe.topic, ["probes", i, "topic"], problems)
    typename = _resolve(src, store, probe.type, ["probes", i, "type"], problems)
    if typename is None:
        return
    for key, signal in probe.signals.items():
        where = ["probes", i, "signals", key]
        path = signal.field or key
        try:
            found = field_type(store, typename, path)
        except RosError as exc:
            at = src.at(where + ["field"]) if signal.field else src.key(
                src.data["probes"][i]["signals"], key
            )
            hint = "" if signal.field else " (give the signal a field: path)"
            problems.append(src.error(f"signal '{key}': {exc}{hint}", at, len(path)))
            continue
        kind = value_type(found)
        if not takes(signal.type, kind):
            problems.append(src.error(
                f"signal '{key}' is {signal.type} but {path} of {typename} is {found} "
                f"({kind}): every value would be refused; declare it {kind}",
                src.at(where + ["type"]),
            ))
    if probe.stamp == "header":
        header = store.fields(typename).get("header")
        if header is None or header.base != "std_msgs/msg/Header" or header.array:
            problems.append(src.error(
                f"probe {probe.topic}: stamp: header, but {typename} has no std_msgs/msg/Header "
                "field 'header' (leave stamp out: records are timed on arrival)",
                src.at(["probes", i, "stamp"]),
            ))


def _check_effector(
    src: YamlSource, store: Any, effector: Effector, problems: list[SourceError]
) -> Effector:
    from rasm.platform.messages import value_type
    from rasm.ros2 import RosError, field_type
    from rasm.ros2.names import interface_kind

    where = ["effectors", effector.name]
    _check_topic(src, effector.topic, where + [effector.kind], problems)
    typename = _resolve(src, store, effector.type, where + ["type"], problems)
    if typename is None:
        return effector
    kind = interface_kind(typename)
    wanted = {"topic": "msg", "service": "srv", "action": "action"}[effector.kind]
    if kind != wanted:
        what = {"msg": "a message", "srv": "a service", "action": "an action"}[kind]
        use = {"msg": "topic", "srv": "service", "action": "action"}[kind]
        problems.append(src.error(
            f"effector {effector.name}: {typename} is {what} type, so the effector needs a "
            f"{use}: (it has a {effector.kind}:), or a pkg/{wanted}/Name type",
            src.at(where + ["type"]), len(effector.type or ""),
        ))
        return effector
    effector = replace(effector, type=typename)
    message = effector.message_type or typename
    kinds: dict[str, str] = {}
    written = src.data["effectors"][effector.name].get("fields") or {}
    for path, key in effector.message_fields.items():
        try:
            found = field_type(store, message, path)
        except RosError as exc:
            problems.append(src.error(
                f"effector {effector.name}: {exc}", src.key(written, path), len(path)
            ))
            continue
        if not PAYLOAD_KEY.match(key):
            problems.append(src.error(
                f"effector {effector.name}: {key!r} is not a payload key (letters, digits and "
                "_, not first a digit); write message field: payload key",
                src.at(where + ["fields", path]),
            ))
            continue
        kind = value_type(found)
        if kinds.setdefault(key, kind) != kind:
            problems.append(src.error(
                f"effector {effector.name}: payload key '{key}' fills fields of two types "
                f"({kinds[key]} and {kind})",
                src.at(where + ["fields", path]),
            ))
    if not effector.message_fields and effector.call is None:
        problems.append(src.error(
            f"effector {effector.name}: list the message fields its actions fill, as "
            "fields: {message.field: payload_key}",
            src.key(src.data["effectors"], effector.name),
        ))
    response = _answer_signals(src, store, effector, "response", effector.answer_type, problems)
    feedback = _answer_signals(
        src, store, effector, "feedback",
        f"{typename}_Feedback" if effector.call == "action" else None, problems,
    )
    return replace(effector, fields=kinds, response=response, feedback=feedback)


def _answer_signals(
    src: YamlSource, store: Any, effector: Effector, part: str, typename: str | None,
    problems: list[SourceError],
) -> dict[str, Signal]:
    """A service or action effector's ``response`` or ``feedback`` signals, each with the
    value type of the answer's field it reads."""
    from rasm.platform.messages import value_type
    from rasm.ros2 import RosError, field_type

    signals: dict[str, Signal] = getattr(effector, part)
    if typename is None or not signals:
        return signals
    written = src.data["effectors"][effector.name].get(part) or {}
    typed = {}
    for key, signal in signals.items():
        path = signal.field or key
        try:
            found = field_type(store, typename, path)
        except RosError as exc:
            problems.append(src.error(
                f"effector {effector.name}: {part}: {exc}", src.key(written, path), len(path)
            ))
            continue
        typed[key] = replace(signal, type=value_type(found))
    return typed
