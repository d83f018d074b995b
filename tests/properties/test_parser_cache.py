"""The property parser's cache: lark keeps the parser it built in the user's cache folder and
unpickles it on the next start, so a cache file only this user could have written is read back —
one owned by someone else, or in a folder others can write to, is not."""

from __future__ import annotations

import os
import pickle
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.properties.cache import trusted as _trusted

PROPERTY = "input a: bool\nproperty p: always a\n"
CHECK = "from rasm.properties import load_specification\nload_specification(open('p.rv').read())\n"


def _status(mode: int, uid: int) -> os.stat_result:
    return os.stat_result((mode, 0, 0, 1, uid, 0, 0, 0, 0, 0))


@given(mode=st.integers(0, 0o7777), other=st.integers(0, 2**31).filter(lambda u: u != os.getuid()))
def test_only_what_this_user_owns_and_no_one_else_can_write_is_trusted(mode: int, other: int):
    writable_by_others = bool(mode & (stat.S_IWGRP | stat.S_IWOTH))
    assert _trusted(_status(stat.S_IFREG | mode, os.getuid())) is not writable_by_others
    assert _trusted(_status(stat.S_IFDIR | mode, os.getuid())) is not writable_by_others
    assert not _trusted(_status(stat.S_IFREG | mode, other))


class _Plant:
    """A pickle that leaves a folder behind when it is loaded: proof the file was unpickled."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.mkdir, (str(self.marker),))


def _parse_in_fresh_process(work: Path, cache: Path) -> None:
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    subprocess.run([sys.executable, "-c", CHECK], cwd=work, env=env, check=True, timeout=60,
                   capture_output=True)


@pytest.fixture
def planted(tmp_path: Path) -> tuple[Path, Path, Path]:
    """(work folder, cache home, marker): a genuine cache file written by a first parse, then
    replaced by one with lark's header and a planted pickle."""
    work, cache, marker = tmp_path / "work", tmp_path / "cache", tmp_path / "unpickled"
    work.mkdir()
    (work / "p.rv").write_text(PROPERTY)
    _parse_in_fresh_process(work, cache)
    [written] = (cache / "rasm").glob("properties-start-*.lark")
    assert not written.stat().st_mode & 0o022
    header = written.read_bytes().split(b"\n", 1)[0] + b"\n"
    written.write_bytes(header + pickle.dumps(_Plant(marker)))
    return work, cache, marker


def test_a_cache_file_this_user_wrote_is_read_back(planted):
    work, cache, marker = planted
    _parse_in_fresh_process(work, cache)
    assert marker.exists()  # the file was unpickled (and the parser rebuilt: it parsed)


def test_a_cache_in_a_folder_others_can_write_to_is_not_read(planted):
    work, cache, marker = planted
    (cache / "rasm").chmod(0o770)
    _parse_in_fresh_process(work, cache)
    assert not marker.exists()


@pytest.mark.skipif(os.getuid() != 0, reason="giving a file to another user needs root")
def test_a_cache_file_someone_else_owns_is_not_read(planted):
    work, cache, marker = planted
    [file] = (cache / "rasm").glob("properties-start-*.lark")
    os.chown(file, 4242, 4242)
    _parse_in_fresh_process(work, cache)
    assert not marker.exists()


# a property file's checked specification, kept for the next command on the same file
SPEC = (
    "import sys\nfrom rasm.properties.loader import cached_specification\n"
    "spec = cached_specification(open('p.rv').read(), 'p.rv')\n"
    "print([p.name for p in spec.properties], 'lark' in sys.modules)\n"
)


def _spec_in_fresh_process(work: Path, cache: Path) -> str:
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    return subprocess.run([sys.executable, "-c", SPEC], cwd=work, env=env, check=True,
                          timeout=60, capture_output=True, text=True).stdout.strip()


def test_an_unchanged_property_file_is_read_back_without_the_parser(tmp_path: Path):
    work, cache = tmp_path / "work", tmp_path / "cache"
    work.mkdir()
    (work / "p.rv").write_text(PROPERTY)
    assert _spec_in_fresh_process(work, cache) == "['p'] True"  # parsed, then kept
    [kept] = (cache / "rasm").glob("spec-*.pickle")
    assert kept.stat().st_mode & 0o777 == 0o600
    assert _spec_in_fresh_process(work, cache) == "['p'] False"  # read back: no lark
    (work / "p.rv").write_text(PROPERTY.replace("property p", "property q"))
    assert _spec_in_fresh_process(work, cache) == "['q'] True"  # changed: parsed again
    assert _spec_in_fresh_process(work, cache) == "['q'] False"


def test_a_kept_specification_in_a_folder_others_can_write_to_is_not_read(tmp_path: Path):
    work, cache, marker = tmp_path / "work", tmp_path / "cache", tmp_path / "unpickled"
    work.mkdir()
    (work / "p.rv").write_text(PROPERTY)
    _spec_in_fresh_process(work, cache)
    [kept] = (cache / "rasm").glob("spec-*.pickle")
    kept.write_bytes(pickle.dumps(_Plant(marker)))
    (cache / "rasm").chmod(0o770)
    assert _spec_in_fresh_process(work, cache) == "['p'] True"
    assert not marker.exists()
    (cache / "rasm").chmod(0o700)
    kept.write_bytes(pickle.dumps(_Plant(marker)))  # (a planted file, as the user's own)
    assert _spec_in_fresh_process(work, cache) == "['p'] True"  # not a specification: loaded


def test_a_kept_specification_is_the_one_loaded():
    from rasm.properties.loader import cached_specification, load_specification

    text = "input x: float\nevent e\nlet big = x > 2\nproperty p: e -> eventually[0, 1.5s] big\n"
    assert cached_specification(text, "<kept>") == load_specification(text, source="<kept>")
    kept = cached_specification(text, "<kept>")
    assert kept == load_specification(text, source="<kept>")
    assert [p.location for p in kept.properties] == [
        p.location for p in load_specification(text, source="<kept>").properties]
