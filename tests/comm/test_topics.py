"""Topic names, patterns and matching follow MQTT 3.1.1 §4.7; the index agrees with matching."""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from paho.mqtt.client import topic_matches_sub

from rasm.comm import CommError
from rasm.comm.topics import TopicIndex, topic_matches, validate_pattern, validate_topic

from .strategies import TOPICS, patterns


def reference_matches(pattern: str, topic: str) -> bool:
    """An independent matcher: the pattern as a regular expression over the topic."""
    if topic.startswith("$") and pattern.split("/")[0] in ("+", "#"):
        return False
    parts = []
    for level in pattern.split("/"):
        if level == "+":
            parts.append("[^/]*")
        elif level == "#":
            parts.append("#")
        else:
            parts.append(re.escape(level))
    regex = "/".join(parts)
    # 'x/#' matches 'x' itself and anything below it; a lone '#' matches everything.
    if regex == "#":
        regex = ".*"
    elif regex.endswith("/#"):
        regex = regex[:-2] + "(/.*)?"
    return re.fullmatch(regex, topic, flags=re.DOTALL) is not None


@pytest.mark.parametrize("topic", ["a", "a/b", "/a", "a/", "$SYS/x", "é/ü", "a b"])
def test_valid_topics_are_accepted(topic):
    assert validate_topic(topic) == topic


@pytest.mark.parametrize("topic", ["", "a/+", "a/#", "+", "a\x00b", 7])
def test_invalid_topics_are_refused(topic):
    with pytest.raises(CommError):
        validate_topic(topic)


@pytest.mark.parametrize("pattern", ["#", "+", "a/#", "+/+/c", "a/+/#", "/#"])
def test_valid_patterns_are_accepted(pattern):
    assert validate_pattern(pattern) == pattern


@pytest.mark.parametrize("pattern", ["", "a/#/b", "a#", "#/a", "a+", "a/+b/c", "##"])
def test_invalid_patterns_are_refused_with_a_hint(pattern):
    with pytest.raises(CommError) as info:
        validate_pattern(pattern)
    assert "pattern" in str(info.value)


@pytest.mark.parametrize(
    ("pattern", "topic", "expected"),
    [
        ("sport/#", "sport", True),
        ("sport/#", "sport/tennis/player1", True),
        ("sport/+", "sport", False),
        ("sport/+", "sport/", True),
        ("+/+", "/finance", True),
        ("/+", "/finance", True),
        ("+", "/finance", False),
        ("#", "$SYS/load", False),
        ("+/load", "$SYS/load", False),
        ("$SYS/#", "$SYS/load", True),
        ("a/b", "a/b", True),
        ("a/b", "a/b/c", False),
    ],
)
def test_examples_from_the_mqtt_standard(pattern, topic, expected):
    assert topic_matches(pattern, topic) is expected


@settings(max_examples=400)
@given(patterns(), TOPICS)
def test_matching_equals_a_regex_reference_and_paho(pattern, topic):
    validate_pattern(pattern)
    expected = reference_matches(pattern, topic)
    assert topic_matches(pattern, topic) is expected
    assert topic_matches_sub(pattern, topic) is expected


@settings(max_examples=150)
@given(st.lists(patterns(), max_size=8), st.lists(TOPICS, min_size=1, max_size=6), st.data())
def test_index_finds_exactly_the_matching_items(pattern_list, topics, data):
    index: TopicIndex[object] = TopicIndex()
    items = [(p, object()) for p in pattern_list]
    for pattern, item in items:
        index.add(pattern, item)
    # remove a few again: the index must forget them (and its memo of earlier answers)
    for topic in topics:
        index.match(topic)
    removed = data.draw(st.sets(st.sampled_from(range(len(items))), max_size=3)) if items else set()
    for i in removed:
        assert index.remove(*items[i])
    kept = [it for i, it in enumerate(items) if i not in removed]
    for topic in topics:
        found = index.match(topic)
        expected = [item for pattern, item in kept if topic_matches(pattern, topic)]
        assert sorted(map(id, found)) == sorted(map(id, expected))
    assert len(index) == len(kept)


def test_removing_an_unknown_item_reports_false():
    index: TopicIndex[object] = TopicIndex()
    assert index.remove("a/+", object()) is False
    assert index.remove("a", object()) is False
