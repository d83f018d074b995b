"""rasm's wheel is kept in the wheelhouse by the state of its source: one build serves every later
packaging, in any process, and a changed, added or removed source file makes a new one."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from rasm.workflow import package_app
from rasm.workflow.package import _source_key

from .helpers import ROOT

HOTBOX = ROOT / "examples" / "hotbox"


def rasm_wheel(package: Path) -> zipfile.ZipFile:
    with zipfile.ZipFile(package) as archive:
        [name] = [n for n in archive.namelist() if n.startswith("01_Binaries/rasm-")]
        (package.parent / "rasm.whl").write_bytes(archive.read(name))
    return zipfile.ZipFile(package.parent / "rasm.whl")


@pytest.mark.slow
def test_a_kept_wheel_is_what_another_process_packages(tmp_path, monkeypatch):
    house = tmp_path / "house"
    monkeypatch.setenv("RASM_WHEELHOUSE", str(house))
    package_app(HOTBOX, tmp_path / "first.zip", dependencies=False)
    [kept] = (house / "rasm" / _source_key(ROOT)).glob("rasm-*.whl")
    # marked: a packaging that builds rasm again instead of taking the kept wheel loses the mark
    with zipfile.ZipFile(kept, "a") as wheel:
        wheel.writestr("rasm/kept-by-the-wheelhouse", "")
    second = tmp_path / "second.zip"
    done = subprocess.run(
        [Path(sys.executable).with_name("rasm"), "package", HOTBOX, "-o", second, "--no-deps"],
        cwd=tmp_path, env={**os.environ, "RASM_WHEELHOUSE": str(house)},
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    with rasm_wheel(second) as wheel:
        assert "rasm/kept-by-the-wheelhouse" in wheel.namelist()


SOURCES = ["pyproject.toml", "README.md", "rasm/__init__.py", "rasm/cli/main.py",
           "statecharts/a.yaml", "monitors/m.yaml", "properties/p.rv"]


def tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


@settings(max_examples=25, deadline=None)
@given(
    files=st.dictionaries(st.sampled_from(SOURCES[2:]), st.text(max_size=5), min_size=1),
    change=st.sampled_from(["edit", "add", "remove"]),
    data=st.data(),
)
def test_any_change_to_the_source_makes_a_new_key(tmp_path_factory, files, change, data):
    root = tree(tmp_path_factory.mktemp("src"), {"pyproject.toml": "", "README.md": "", **files})
    before = _source_key(root)
    assert _source_key(root) == before
    if change == "edit":
        name = data.draw(st.sampled_from(sorted(files)))
        path = root / name
        stat = path.stat()
        path.write_text(files[name] + "x")
        os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))  # within one clock tick: by size
    elif change == "add":
        absent = [n for n in SOURCES[2:] if n not in files]
        assume(absent)
        tree(root, {data.draw(st.sampled_from(absent)): ""})
    else:
        (root / data.draw(st.sampled_from(sorted(files)))).unlink()
    after = _source_key(root)
    assert after != before
    tree(root, {"rasm/__pycache__/main.cpython-311.pyc": "0"})  # bytecode is not source
    assert _source_key(root) == after
