"""Small deployment packages built by hand: the layout `rasm deploy` reads, no wheels.

The actions only write a marker file, so a package that passes verification deploys in
milliseconds and shows that its workflow ran.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

from rasm.workflow.derive import host_arch
from rasm.workflow.integrity import MANIFEST, SIGNATURE, digest, manifest_bytes, sign

UNIT = "local"
WORKFLOWS = {
    "workflows": {"deploy": {"steps": ["install"]}, "start": {"steps": ["install"]}},
    "actions": {"install": "05_Actions/install.sh"},
}


def unit_config(**changes: object) -> dict[str, object]:
    config: dict[str, object] = {
        "unit": UNIT, "arch": host_arch(), "role": "all", "transport": "local",
        "clock": "simulated", "knowledge": "memory", "app_module": "app", "app_dist": "app",
        "binaries": "01_Binaries/any",
    }
    config.update(changes)
    return config


def files(**extra: bytes) -> dict[str, bytes]:
    """A minimal valid package's files (``extra`` added, by name with '__' for '/')."""
    out = {  # JSON is YAML
        f"04_Platform/{UNIT}.yaml": json.dumps(unit_config()).encode(),
        "06_Workflows/workflows.yaml": json.dumps(WORKFLOWS).encode(),
        "05_Actions/install.sh": b'touch "$RASM_DIR/installed"\n',
    }
    out.update({name.replace("__", "/"): data for name, data in extra.items()})
    return out


def build(
    path: Path,
    contents: dict[str, bytes],
    *,
    listed: dict[str, str] | None = None,
    key: bytes | None = None,
    manifest: bytes | None = None,
) -> Path:
    """Write a zip of ``contents`` with a MANIFEST.json of their digests (or ``listed``, or
    the raw ``manifest`` bytes), signed with ``key`` when given."""
    if manifest is None:
        listed = {n: digest(d) for n, d in contents.items()} if listed is None else listed
        manifest = manifest_bytes({"files": listed, "units": [UNIT]})
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr(MANIFEST, manifest)
        if key is not None:
            archive.writestr(SIGNATURE, sign(manifest, key))
        for name, data in contents.items():
            archive.writestr(name, data)
    return path


def written(target: Path) -> list[str]:
    """Every file under ``target`` (relative), to show that nothing was written."""
    if not target.exists():
        return []
    return sorted(str(p.relative_to(target)) for p in target.rglob("*") if p.is_file())


__all__ = ["UNIT", "build", "files", "unit_config", "written"]
