"""A package zip read with bounded memory, whatever its entries claim to hold.

A zip's central directory says what each entry is (name, compressed and uncompressed size)
without reading it. So, in this order, and before any entry's content is read whole:

1. every entry's name is checked (plain relative paths, no duplicates);
2. ``MANIFEST.json`` (at most :data:`MAX_MANIFEST` bytes) and its signature are read, and the
   signature is checked;
3. no entry may expand more than :data:`MAX_RATIO` times (past 1 MiB), nor all of them past
   :data:`MAX_TOTAL` bytes: that refuses a zip bomb from the zip's directory alone;
4. the manifest's file list is compared with the entries by name, and the sizes it declares
   with the sizes the zip declares; no file may also be the folder of another;
5. every entry is streamed through SHA-256 in chunks of :data:`CHUNK` bytes, never past its
   declared size.

Only then are small files (a unit's configuration, the workflows) read whole, under a cap, and
the package extracted, streamed again and re-hashed so that a zip changed in between is caught.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import IO, Any

from rasm.workflow.integrity import MANIFEST, SIGNATURE, IntegrityError, shown, verify_signature

__all__ = [
    "CHUNK",
    "MAX_MANIFEST",
    "MAX_RATIO",
    "MAX_SMALL_FILE",
    "MAX_TOTAL",
    "Package",
    "open_package",
]

CHUNK = 1 << 20  # bytes read at a time from an entry
MAX_MANIFEST = 16 << 20  # MANIFEST.json: a line per file, far below this
MAX_SIGNATURE = 4096  # MANIFEST.json.hmac: 64 hex digits and a newline
MAX_SMALL_FILE = 4 << 20  # a file deploy reads whole (the unit's YAML, the workflows)
MAX_TOTAL = 4 << 30  # all entries expanded: the Hotbox with every dependency is 52 MB
MAX_RATIO = 200  # expanded / compressed, for entries over 1 MiB (a package's files: under 5)
_NAME_BYTES = 255  # the longest file or folder name Linux file systems take


def check_entry(name: str) -> None:
    """Refuse an entry name that could write outside the package folder, or that names one file
    in two ways (``a//b``, ``./a``): extraction writes exactly the names verified."""
    path = PurePosixPath(name)
    if path.is_absolute() or ".." in path.parts or "\\" in name:
        raise IntegrityError(f"{shown(name)}: a path outside the package")
    if str(path) != name or name in ("", "."):
        raise IntegrityError(f"{name!r}: not a plain relative path (write {str(path)!r})")
    if any(ord(c) < 32 or c == "\x7f" for c in name):
        raise IntegrityError(f"{name!r}: a control character in a file name")
    if any(len(part.encode("utf-8", "surrogateescape")) > _NAME_BYTES for part in path.parts):
        raise IntegrityError(f"{shown(name[:60])}...: a name longer than {_NAME_BYTES} bytes")


def check_layout(names: list[str]) -> None:
    """Refuse a file that is also a folder of another entry (``X`` and ``X/file``): extraction
    would fail half-way, after writing."""
    folders = {str(parent) for name in names for parent in PurePosixPath(name).parents}
    for name in sorted(names):
        if name in folders:
            inside = next(n for n in sorted(names) if n.startswith(name + "/"))
            raise IntegrityError(f"{shown(name)}: both a file and the folder of {shown(inside)}")


def _check_sizes(entries: dict[str, zipfile.ZipInfo]) -> None:
    """A zip bomb is refused from the sizes the zip declares, before anything is read."""
    total = 0
    for name, info in entries.items():
        total += info.file_size
        ratio = info.file_size / max(info.compress_size, 1)
        if info.file_size > (1 << 20) and ratio > MAX_RATIO:
            raise IntegrityError(
                f"{shown(name)}: expands {ratio:.0f} times ({info.compress_size} to "
                f"{info.file_size} bytes), past {MAX_RATIO}: a zip bomb, not a package file"
            )
    if total > MAX_TOTAL:
        raise IntegrityError(
            f"the entries expand to {total} bytes, past the {MAX_TOTAL} a package may hold"
        )


@dataclass
class Package:
    """A package whose signature, file list, sizes and checksums were verified.

    ``entries`` maps each file's name to its zip entry; ``manifest`` is the parsed
    ``MANIFEST.json``; ``signature`` says what was checked of the signature.
    """

    path: Path
    manifest: dict[str, Any]
    signature: str
    entries: dict[str, zipfile.ZipInfo]

    def read(self, name: str) -> bytes:
        """The content of the small file ``name`` (at most :data:`MAX_SMALL_FILE` bytes),
        checked against its SHA-256 again."""
        try:
            with zipfile.ZipFile(self.path) as archive:
                data = _read_whole(archive, self.entries[name], MAX_SMALL_FILE)
        except (zipfile.BadZipFile, OSError) as exc:
            raise IntegrityError(f"{self.path}: cannot be read again ({exc})") from None
        if hashlib.sha256(data).hexdigest() != self.manifest["files"].get(name):
            raise IntegrityError(f"{shown(name)}: changed while being deployed (SHA-256 differs)")
        return data

    def extract(self, folder: Path) -> None:
        """Write every file under ``folder`` (created), streamed and checked against its
        SHA-256 again; on a mismatch ``folder`` is removed and IntegrityError raised."""
        files: dict[str, str] = self.manifest["files"]
        try:
            with zipfile.ZipFile(self.path) as archive:
                for name, info in self.entries.items():
                    out = folder / name
                    out.parent.mkdir(parents=True, exist_ok=True)
                    with _opened(archive, info) as source, out.open("wb") as sink:
                        found = _stream(source, info, sink)
                    if name in files and found != files[name]:
                        raise IntegrityError(
                            f"{shown(name)}: changed while being deployed (SHA-256 differs)"
                        )
                    if name.endswith(".sh"):
                        out.chmod(0o755)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)  # nothing half-extracted is left
            raise


@contextmanager
def _opened(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> Iterator[IO[bytes]]:
    try:
        with archive.open(info) as source:
            yield source
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError,
            ValueError, RuntimeError, OSError) as exc:
        raise IntegrityError(f"{shown(info.filename)}: cannot be read ({exc})") from None


def _stream(source: IO[bytes], info: zipfile.ZipInfo, sink: IO[bytes] | None = None) -> str:
    """The SHA-256 of an entry read in chunks, never past its declared size (``sink``: also
    written there)."""
    digest = hashlib.sha256()
    left = info.file_size
    while True:
        try:
            chunk = source.read(min(CHUNK, left + 1))
        except (zipfile.BadZipFile, EOFError, ValueError, RuntimeError, OSError) as exc:
            raise IntegrityError(f"{shown(info.filename)}: cannot be read ({exc})") from None
        if not chunk:
            break
        left -= len(chunk)
        if left < 0:
            raise IntegrityError(f"{shown(info.filename)}: longer than its declared size")
        digest.update(chunk)
        if sink is not None:
            sink.write(chunk)
    if left:
        raise IntegrityError(f"{shown(info.filename)}: shorter than its declared size")
    return digest.hexdigest()


def _read_whole(archive: zipfile.ZipFile, info: zipfile.ZipInfo, limit: int) -> bytes:
    if info.file_size > limit:
        raise IntegrityError(
            f"{shown(info.filename)}: {info.file_size} bytes, more than the {limit} it may have"
        )
    with _opened(archive, info) as source:
        data = source.read(limit + 1)
    if len(data) != info.file_size:
        raise IntegrityError(f"{shown(info.filename)}: not the size its entry declares")
    return data


def _listing(raw: bytes, entries: dict[str, zipfile.ZipInfo]) -> dict[str, Any]:
    """The manifest, its file list matching the entries by name and declared size."""
    try:
        manifest = json.loads(raw)
    except (ValueError, RecursionError) as exc:  # not JSON, not UTF-8, nested too deep
        raise IntegrityError(f"{MANIFEST}: not JSON ({exc})") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("files"), dict):
        raise IntegrityError(f"{MANIFEST}: no file list")
    files: dict[str, Any] = manifest["files"]
    for name, expected in sorted(files.items()):
        if name not in entries:
            raise IntegrityError(
                f"{shown(name)}: listed in {MANIFEST} but missing from the package"
            )
        if not isinstance(expected, str):
            raise IntegrityError(f"{MANIFEST}: the SHA-256 of {shown(name)} is not a string")
    extra = sorted(set(entries) - set(files) - {MANIFEST, SIGNATURE})
    if extra:
        raise IntegrityError(f"{shown(extra[0])}: in the package but not listed in {MANIFEST}")
    sizes = manifest.get("sizes")
    if sizes is not None:  # packages from before rasm declared sizes have the zip's only
        if not isinstance(sizes, dict):
            raise IntegrityError(f"{MANIFEST}: 'sizes' is not a mapping of file to bytes")
        for name in sorted(files):
            declared = sizes.get(name)
            if type(declared) is not int or declared != entries[name].file_size:
                raise IntegrityError(
                    f"{shown(name)}: size does not match {MANIFEST} (file changed: "
                    f"{entries[name].file_size} bytes, {declared!r} declared)"
                )
    return manifest


def open_package(package: str | Path, key: bytes | None) -> Package:
    """Verify the package at ``package`` (see the module's docstring for the order); raises
    :class:`IntegrityError` naming what is wrong."""
    path = Path(package)
    try:
        with zipfile.ZipFile(path) as archive:
            entries: dict[str, zipfile.ZipInfo] = {}
            for info in archive.infolist():
                if info.is_dir():
                    continue
                check_entry(info.filename)
                if info.filename in entries:
                    raise IntegrityError(f"{shown(info.filename)}: appears twice in the package")
                entries[info.filename] = info
            if MANIFEST not in entries:
                raise IntegrityError(f"{path}: no {MANIFEST}: not a rasm package")
            raw = _read_whole(archive, entries[MANIFEST], MAX_MANIFEST)
            signed = entries.get(SIGNATURE)
            signature = verify_signature(
                raw, _read_whole(archive, signed, MAX_SIGNATURE) if signed else None, key
            )
            _check_sizes(entries)
            manifest = _listing(raw, entries)
            check_layout(list(entries))
            for name, expected in sorted(manifest["files"].items()):
                with _opened(archive, entries[name]) as source:
                    if _stream(source, entries[name]) != expected:
                        raise IntegrityError(
                            f"{shown(name)}: SHA-256 does not match {MANIFEST} (file changed)"
                        )
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError) as exc:
        raise IntegrityError(f"{path}: not a package (bad zip: {exc})") from None
    except FileNotFoundError:
        raise IntegrityError(f"{path}: no such package") from None
    except IsADirectoryError:
        raise IntegrityError(f"{path}: a folder, not a package") from None
    except (ValueError, RuntimeError) as exc:  # an encrypted entry, a bad compression header
        raise IntegrityError(f"{path}: not a package ({exc})") from None
    return Package(path, manifest, signature, entries)
