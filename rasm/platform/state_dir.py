"""Where an app's state lives by default: ``.rasm/<app name>/`` under the working directory,
claimed by the app folder it belongs to so that two apps of one name never share knowledge."""

from __future__ import annotations

import hashlib
from pathlib import Path

from rasm.platform.manifest import AppManifest

__all__ = ["APP_CLAIM", "claim_state_dir", "default_state_dir"]

APP_CLAIM = "app"  # in a state folder: the app folder whose state it holds


def default_state_dir(manifest: AppManifest) -> Path:
    """``.rasm/<app name>``, unless another app of that name has it: then
    ``.rasm/<app name>-<hash of the app folder>``, so two apps never share knowledge."""
    base = Path(".rasm") / manifest.name
    claim = base / APP_CLAIM
    folder = str(manifest.folder.resolve())
    try:
        owner = claim.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return base
    if owner in ("", folder):
        return base
    digest = hashlib.sha256(folder.encode("utf-8")).hexdigest()[:10]
    return Path(".rasm") / f"{manifest.name}-{digest}"


def claim_state_dir(state_dir: Path, manifest: AppManifest) -> None:
    """Mark the default state folder as ``manifest``'s app's (see :func:`default_state_dir`)."""
    state_dir.mkdir(parents=True, exist_ok=True)
    claim = state_dir / APP_CLAIM
    if not claim.exists():
        claim.write_text(f"{manifest.folder.resolve()}\n", encoding="utf-8")
