"""rasm.yamltext: YAML read exactly as sismic reads it, with the place of everything in it.

The guards against hostile documents are tested in tests/hostile/test_bad_files.py.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from ruamel.yaml import YAML
from ruamel.yaml.error import YAMLError

from rasm.errors import Location, SourceError
from rasm.yamltext import load_yaml, plain

# scalars that YAML 1.1 (PyYAML) and YAML 1.2 (ruamel, sismic) read differently, and others
TOKENS = [
    "on", "off", "yes", "no", "y", "n", "On", "YES", "true", "False", "~", "null", "",
    "0o17", "017", "0x1F", "1_000", "1:30", "1e3", "1.5", ".inf", "-.inf", ".nan", "0.",
    "2021-01-01", "'on'", '"yes"', "[on, off]", "{a: on}", "x y", "- z",
]
SAFE_TEXT = st.text(st.characters(categories=("L", "N")), min_size=1, max_size=8)


def sismic_reading(text: str):
    """What sismic's YAML import reads (sismic.io.import_from_yaml)."""
    return YAML(typ="safe", pure=True).load(text)


def same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b or (isinstance(a, float) and a == b)


@given(st.lists(st.tuples(SAFE_TEXT, st.sampled_from(TOKENS) | SAFE_TEXT), max_size=6,
                unique_by=lambda pair: pair[0]))
def test_yaml_is_read_as_sismic_reads_it(pairs):
    text = "".join(f"k{key}: {value}\n" for key, value in pairs)
    try:
        expected = sismic_reading(text)
    except YAMLError:
        with pytest.raises(SourceError):
            load_yaml(text, "t.yaml")
        return
    assert same(plain(load_yaml(text, "t.yaml").data), expected)


@pytest.mark.parametrize("word", ["on", "off", "yes", "no", "y", "n"])
def test_yaml_1_1_booleans_stay_strings(word):
    assert plain(load_yaml(f"{word}: {word}\n", "t.yaml").data) == {word: word}


def test_every_key_value_and_item_has_its_place():
    src = load_yaml("name: box\nsignals:\n  t: {type: float}\nlist:\n  - a\n  - b: 1\n", "a.yaml")
    assert src.key(src.data, "signals") == Location("a.yaml", 2, 1)
    assert src.value(src.data, "name") == Location("a.yaml", 1, 7)
    assert src.at(["signals", "t", "type"]) == Location("a.yaml", 3, 13)
    assert src.item(src.data["list"], 1) == Location("a.yaml", 6, 5)
    # a key the document lacks is reported where its mapping is written (the key "t")
    assert src.at(["signals", "t", "max"]) == Location("a.yaml", 3, 3)


def test_a_syntax_error_is_a_source_error_at_its_place_with_the_line_marked():
    with pytest.raises(SourceError) as caught:
        load_yaml("a: 1\nb: [1, 2\n", "bad.yaml")
    error = caught.value
    assert error.location.file == "bad.yaml" and error.location.line == 3
    assert error.message.startswith("YAML syntax error:")


def test_a_scalar_keeps_how_it_was_quoted_when_asked():
    src = load_yaml("when: 'x > 1'\n", "r.yaml", preserve_quotes=True)
    assert type(src.data["when"]).__name__ == "SingleQuotedScalarString"
    assert type(plain(src.data)["when"]) is str
