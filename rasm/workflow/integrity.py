"""A package's integrity: a manifest with the SHA-256 of every file, optionally signed.

``MANIFEST.json`` lists every file of the package with its SHA-256 (``files``) and its size in
bytes (``sizes``); ``MANIFEST.json.hmac`` (when
a key is configured) is the HMAC-SHA256 of the manifest's exact bytes, hex-encoded. The key comes
from configuration: the environment variable ``RASM_PACKAGE_KEY`` (the key itself), or a key file
(``--key-file`` or ``RASM_PACKAGE_KEY_FILE``; its bytes, surrounding whitespace stripped).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
from pathlib import Path
from typing import Any

from rasm.errors import RasmError

__all__ = [
    "MANIFEST",
    "SIGNATURE",
    "IntegrityError",
    "configured_key",
    "digest",
    "manifest_bytes",
    "shown",
    "sign",
    "verify_signature",
]

MANIFEST = "MANIFEST.json"
SIGNATURE = "MANIFEST.json.hmac"


class IntegrityError(RasmError):
    """A package that must not be installed: a changed, missing or extra file, a bad signature."""


def shown(name: str) -> str:
    """An entry name for a message: as it is, or quoted with escapes when it is not printable."""
    return name if name.isprintable() else repr(name)


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def configured_key(key_file: str | Path | None = None) -> bytes | None:
    """The signing key from ``key_file``, ``RASM_PACKAGE_KEY_FILE`` or ``RASM_PACKAGE_KEY``."""
    file = key_file or os.environ.get("RASM_PACKAGE_KEY_FILE")
    if file:
        try:
            key = Path(file).read_bytes().strip()
        except OSError as exc:
            raise IntegrityError(f"cannot read the package key file {file}: {exc}") from None
        if not key:
            raise IntegrityError(f"the package key file {file} is empty")
        return key
    text = os.environ.get("RASM_PACKAGE_KEY")
    return text.encode("utf-8") if text else None


def sign(manifest: bytes, key: bytes) -> str:
    """The HMAC-SHA256 of the manifest's bytes, hex."""
    return hmac.new(key, manifest, hashlib.sha256).hexdigest()


def verify_signature(manifest: bytes, signature: bytes | None, key: bytes | None) -> str:
    """Check the signature against ``key``; returns what was checked, raises on a mismatch.

    With a key configured an unsigned package is refused; without one a signed package is
    accepted on its checksums alone (and the caller says so).
    """
    if key is None:
        return "unsigned" if signature is None else "signed, not verified (no key configured)"
    if signature is None:
        raise IntegrityError(
            f"the package is not signed ({SIGNATURE} missing) but a key is configured: refusing it"
        )
    expected = sign(manifest, key)
    if not hmac.compare_digest(expected, signature.decode("ascii", "replace").strip()):
        raise IntegrityError(f"{SIGNATURE}: the signature does not match the configured key")
    return "signature verified (HMAC-SHA256)"


def manifest_bytes(data: dict[str, Any]) -> bytes:
    return (json.dumps(data, indent=2, sort_keys=True) + "\n").encode("utf-8")
