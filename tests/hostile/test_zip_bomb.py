"""A zip bomb (a 1 MB package holding 1 GiB) is refused with exit 2 before any entry is read
whole: from the sizes the zip declares, after the signature, never by inflating it. The deploy
runs in a subprocess whose peak RSS is measured (it was 2 GB: every entry was read at once)."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from rasm.workflow.integrity import MANIFEST, SIGNATURE, digest, manifest_bytes, sign

from .packages import UNIT, files, written

GIB = 1 << 30
BOMB = "02_Nodes/bomb.bin"
KEY = b"bomb squad"
# the deploy's peak RSS, whatever the bomb: Python and rasm's imports take about 40 MB here
RSS_LIMIT_MB = 150

# the peak RSS of this process's own memory (VmHWM): getrusage's ru_maxrss would also count the
# pytest process it was forked from
_MEASURE = """
import sys
from rasm.cli import main
code = main(sys.argv[1:])
with open("/proc/self/status") as status:
    peak = next(line.split()[1] for line in status if line.startswith("VmHWM:"))
print(f"maxrss_kb={peak}", file=sys.stderr)
sys.exit(code)
"""


def _bomb_digest() -> str:
    zeros, sha = bytes(1 << 20), hashlib.sha256()
    for _ in range(GIB >> 20):
        sha.update(zeros)
    return sha.hexdigest()


def build_bomb(path: Path, *, listed: bool, key: bytes | None = None) -> Path:
    """A minimal valid package plus 1 GiB of zeros deflated to about 1 MB; ``listed``: the
    manifest names the bomb with its true SHA-256 and size (a self-consistent package)."""
    contents = files()
    sums = {name: digest(data) for name, data in contents.items()}
    sizes = {name: len(data) for name, data in contents.items()}
    if listed:
        sums[BOMB], sizes[BOMB] = _bomb_digest(), GIB
    manifest = manifest_bytes({"files": sums, "sizes": sizes, "units": [UNIT]})
    zeros = bytes(1 << 20)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(MANIFEST, manifest)
        if key is not None:
            archive.writestr(SIGNATURE, sign(manifest, key))
        for name, data in contents.items():
            archive.writestr(name, data)
        with archive.open(BOMB, "w", force_zip64=True) as out:
            for _ in range(GIB >> 20):
                out.write(zeros)
    return path


@pytest.fixture(scope="module")
def bombs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("bombs")
    return {
        "unlisted": build_bomb(folder / "unlisted.zip", listed=False),
        "listed": build_bomb(folder / "listed.zip", listed=True),
    }


def deploy_measured(package: Path, target: Path, env: dict[str, str]) -> tuple[int, str, float]:
    """``rasm deploy`` in a subprocess: its exit code, its output and its peak RSS in MB."""
    done = subprocess.run(
        [sys.executable, "-c", _MEASURE, "deploy", str(package), "--unit", UNIT, "--to",
         str(target)],
        capture_output=True, text=True, env=env, timeout=300,
    )
    lines = done.stderr.splitlines()
    rss = [int(line.split("=")[1]) for line in lines if line.startswith("maxrss_kb=")]
    assert rss, done.stderr
    output = "\n".join(line for line in lines if not line.startswith("maxrss_kb=")) + done.stdout
    return done.returncode, output, rss[0] / 1024


@pytest.fixture
def env() -> dict[str, str]:
    """This environment without a package key."""
    return {k: v for k, v in os.environ.items() if not k.startswith("RASM_PACKAGE_KEY")}


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["unlisted", "listed"])
def test_a_zip_bomb_is_refused_from_its_declared_sizes_with_bounded_memory(
    bombs: dict[str, Path], tmp_path: Path, env: dict[str, str], kind: str
) -> None:
    assert bombs[kind].stat().st_size < 2 << 20  # a 1 MB zip ...
    with zipfile.ZipFile(bombs[kind]) as archive:
        assert archive.getinfo(BOMB).file_size == GIB  # ... holding 1 GiB
    code, out, rss = deploy_measured(bombs[kind], tmp_path / "t", env)
    assert code == 2, out
    assert f"rasm: {BOMB}: expands" in out and "a zip bomb, not a package file" in out, out
    assert "Traceback" not in out
    assert rss < RSS_LIMIT_MB, f"peak RSS {rss:.0f} MB"
    assert written(tmp_path / "t") == []


@pytest.mark.slow
def test_with_a_key_an_unsigned_bomb_is_refused_at_its_signature(
    bombs: dict[str, Path], tmp_path: Path, env: dict[str, str]
) -> None:
    env = {**env, "RASM_PACKAGE_KEY": KEY.decode()}
    code, out, rss = deploy_measured(bombs["listed"], tmp_path / "t", env)
    assert code == 2 and "the package is not signed" in out, out
    assert rss < RSS_LIMIT_MB, f"peak RSS {rss:.0f} MB"
    assert written(tmp_path / "t") == []


@pytest.mark.slow
def test_a_manifest_that_is_itself_a_bomb_is_not_read(tmp_path: Path, env: dict[str, str]):
    package = tmp_path / "p.zip"
    with zipfile.ZipFile(package, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open(MANIFEST, "w", force_zip64=True) as out:
            out.write(b'{"files": {}, "padding": "')
            for _ in range(256):
                out.write(b" " * (1 << 20))
            out.write(b'"}')
    code, out, rss = deploy_measured(package, tmp_path / "t", env)
    assert code == 2 and f"{MANIFEST}: " in out and "more than the" in out, out
    assert rss < RSS_LIMIT_MB, f"peak RSS {rss:.0f} MB"


def test_sizes_the_manifest_declares_must_be_the_zips(tmp_path: Path, env: dict[str, str]):
    contents = files()
    sums = {name: digest(data) for name, data in contents.items()}
    sizes = {name: len(data) for name, data in contents.items()}
    sizes["05_Actions/install.sh"] += 1
    package = tmp_path / "p.zip"
    with zipfile.ZipFile(package, "w") as archive:
        archive.writestr(MANIFEST, json.dumps({"files": sums, "sizes": sizes}))
        for name, data in contents.items():
            archive.writestr(name, data)
    code, out, _ = deploy_measured(package, tmp_path / "t", env)
    assert code == 2, out
    assert "05_Actions/install.sh: size does not match MANIFEST.json (file changed" in out, out
