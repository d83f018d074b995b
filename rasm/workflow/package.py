"""``rasm package``: a deployment package in the RoboSAPIENS layout.

::

    00_Documentation/  README.md, architecture.md (Mermaid diagrams), model.yaml
    01_Binaries/       wheels of the app and of rasm; <platform>/ the dependencies' wheels per CPU
    02_Nodes/          one descriptor per component: maple_k/<stage>/ and managed_system/
    03_Messages/       a JSON Schema per message type (and the app's messages.py)
    04_Platform/       per compute unit: role, transport, knowledge store, clock, checks
    05_Actions/        install, validate, run, stop (POSIX sh scripts)
    06_Workflows/      the trustworthiness checklist and workflows.yaml (actions chained)
    MANIFEST.json      SHA-256 and size of every file; MANIFEST.json.hmac when a key is configured

Wheels are real: ``pip wheel --no-deps`` of rasm's source tree and of the app (staged as package
``rasm_app_NAME``), and ``pip download --only-binary=:all:`` of rasm's dependencies for each CPU
architecture the model's units use, so a unit installs with no network.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML

import rasm
from rasm.errors import RasmError, SourceErrors
from rasm.loop import STAGES
from rasm.workflow.checks import check_model
from rasm.workflow.derive import host_arch, model_from_manifest
from rasm.workflow.diagrams import (
    deployment_diagram,
    logical_diagram,
    model_to_dict,
    physical_diagram,
)
from rasm.workflow.generate import templates
from rasm.workflow.integrity import MANIFEST, SIGNATURE, digest, manifest_bytes, sign
from rasm.workflow.model import ArchitectureModel, ComputeUnit, load_model

__all__ = [
    "PackageError",
    "PackageReport",
    "app_module",
    "package_app",
    "platform_tag",
    "wheelhouse",
]

FORMAT = "rasm-package/1"
_MACHINE = {
    "amd64": "x86_64",
    "arm64": "aarch64",
    "armv7": "armv7l",
    "riscv64": "riscv64",
    "x86": "i686",
}
_SKIP = {".rasm", "__pycache__", ".pytest_cache", ".hypothesis", ".rasm-orphans", ".git"}


class PackageError(RasmError):
    """The package cannot be built (a wheel that does not build, dependencies not found)."""


@dataclass
class PackageReport:
    """What ``rasm package`` wrote."""

    output: Path
    app: str
    files: int
    size: int
    wheels: list[str] = field(default_factory=list)
    units: list[str] = field(default_factory=list)
    signed: bool = False
    derived_model: bool = False
    checklist_failures: list[str] = field(default_factory=list)


def app_module(name: str) -> str:
    """The import name of an app's wheel package."""
    return "rasm_app_" + "".join(c if c.isalnum() else "_" for c in name)


def platform_tag(unit: ComputeUnit) -> str:
    """The 01_Binaries sub-folder holding a unit's dependency wheels (e.g. linux_x86_64)."""
    return f"{unit.os}_{_MACHINE.get(unit.arch, unit.arch)}"


def _pip_command(args: list[str]) -> list[str]:
    return [sys.executable, "-m", "pip", *args, "--disable-pip-version-check"]


def _pip_failed(args: list[str], what: str, output: str) -> PackageError:
    tail = "\n".join(output.strip().splitlines()[-15:])
    return PackageError(f"{what} failed (pip {' '.join(args[:2])}):\n{tail}")


def _pip(args: list[str], what: str) -> str:
    done = subprocess.run(_pip_command(args), capture_output=True, text=True)
    if done.returncode != 0:
        raise _pip_failed(args, what, done.stderr or done.stdout)
    return done.stdout


def _rasm_source() -> Path:
    root = Path(rasm.__file__).resolve().parent.parent
    pyproject = root / "pyproject.toml"
    if not pyproject.is_file() or 'name = "rasm"' not in pyproject.read_text(encoding="utf-8"):
        raise PackageError(
            f"rasm is installed without its source tree (looked in {root}): install it from a "
            "checkout (pip install -e .) to package applications"
        )
    return root


def _source_key(root: Path) -> str:
    """A digest of every file rasm's wheel is built from (path, size, modification time): the
    name of that wheel's folder in the wheelhouse, so an edited, added or removed file makes a
    new one."""
    files = [root / "pyproject.toml", root / "README.md"]
    for folder in ("rasm", "statecharts", "monitors", "properties"):
        files += (p for p in (root / folder).rglob("*") if "__pycache__" not in p.parts)
    seen = hashlib.sha256()
    for path in sorted(p for p in files if p.is_file()):
        stat = path.stat()
        seen.update(f"{path.relative_to(root)}\0{stat.st_size}\0{stat.st_mtime_ns}\n".encode())
    return seen.hexdigest()[:16]


def _keep(fresh: Path, kept: Path) -> Path:
    """The folder of rasm's fresh wheel once it is kept in the wheelhouse as ``kept`` (whole or
    not at all), or ``fresh`` itself where the wheelhouse cannot take it."""
    try:
        kept.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=kept.parent))
        for wheel in fresh.glob("*.whl"):
            shutil.copy(wheel, staging / wheel.name)
    except OSError:
        return fresh
    try:
        staging.rename(kept)
    except OSError:  # another packaging kept the same wheel first
        shutil.rmtree(staging, ignore_errors=True)
        return kept if kept.is_dir() else fresh
    return kept


def _stage_app(app: Path, name: str, stage: Path) -> None:
    version = metadata.version("rasm")
    package = stage / app_module(name)
    shutil.copytree(
        app,
        package,
        ignore=lambda _d, names: [n for n in names if n in _SKIP or n.endswith(".pyc")],
    )
    init = package / "__init__.py"
    if not init.exists():
        init.write_text(
            f'"""The {name} application, packaged by rasm (run it: rasm run <this folder>)."""\n',
            encoding="utf-8",
        )
    (stage / "pyproject.toml").write_text(
        "[build-system]\n"
        'requires = ["hatchling>=1.21"]\n'
        'build-backend = "hatchling.build"\n\n'
        "[project]\n"
        f'name = "{app_module(name).replace("_", "-")}"\n'
        'version = "0.1.0"\n'
        f'description = "The {name} application on rasm"\n'
        'requires-python = ">=3.11"\n'
        f'dependencies = ["rasm=={version}"]\n\n'
        "[tool.hatch.build.targets.wheel]\n"
        f'packages = ["{app_module(name)}"]\n',
        encoding="utf-8",
    )


def _build_wheels(app: Path, name: str, binaries: Path, work: Path) -> list[Path]:
    """``pip wheel --no-deps`` of rasm and of the app, side by side; returns the wheels."""
    root = _rasm_source()
    # rasm's wheel is kept in the wheelhouse by the state of its source: one build serves every
    # packaging (and every process) until a source file changes
    built = wheelhouse() / "rasm" / _source_key(root)
    stage = work / "app-project"
    _stage_app(app, name, stage)
    builds = {f"building the wheel of {name}": (work / "app-wheel", str(stage))}
    if not built.is_dir():
        builds["building rasm's wheel"] = (work / "rasm-wheel", str(root))
    running = []
    for what, (out, source) in builds.items():
        args = ["wheel", "--no-deps", "--wheel-dir", str(out), source]
        process = subprocess.Popen(
            _pip_command(args), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        running.append((what, args, out, process))
    for what, args, _out, process in running:
        output, _ = process.communicate()
        if process.returncode != 0:
            raise _pip_failed(args, what, output)
    if not built.is_dir():
        built = _keep(work / "rasm-wheel", built)
    [rasm_wheel] = sorted(built.glob("rasm-*.whl"))
    shutil.copy(rasm_wheel, binaries / rasm_wheel.name)
    [app_wheel] = sorted((work / "app-wheel").glob("*.whl"))
    shutil.copy(app_wheel, binaries / app_wheel.name)
    return [binaries / rasm_wheel.name, binaries / app_wheel.name]


def wheelhouse() -> Path:
    """Where downloaded dependency wheels are kept between packagings (``RASM_WHEELHOUSE``)."""
    configured = os.environ.get("RASM_WHEELHOUSE")
    if configured:
        return Path(configured)
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache) / "rasm" / "wheelhouse"


def _download_dependencies(rasm_wheel: Path, unit: ComputeUnit, dest: Path) -> None:
    """rasm's dependencies for ``unit``'s platform into ``dest``: from the wheelhouse when it
    has them all (no network), else downloaded into the wheelhouse first."""
    dest.mkdir(parents=True, exist_ok=True)
    house = wheelhouse() / platform_tag(unit)
    house.mkdir(parents=True, exist_ok=True)
    target: list[str] = []
    python = unit.python or f"{sys.version_info.major}.{sys.version_info.minor}"
    if unit.arch != host_arch() or python != f"{sys.version_info.major}.{sys.version_info.minor}":
        machine = _MACHINE.get(unit.arch, unit.arch)
        for tag in ("manylinux2014", "manylinux_2_17", "manylinux_2_28", "linux"):
            target += ["--platform", f"{tag}_{machine}"]
        target += ["--python-version", python, "--implementation", "cp"]
    common = ["download", "--only-binary=:all:", *target, "--find-links", str(rasm_wheel.parent)]
    offline = [
        *common,
        "--no-index",
        "--find-links",
        str(house),
        "--dest",
        str(dest),
        str(rasm_wheel),
    ]
    done = subprocess.run(_pip_command(offline), capture_output=True, text=True)
    if done.returncode != 0:
        _pip(
            [*common, "--dest", str(house), str(rasm_wheel)],
            f"downloading rasm's dependencies for {unit.name} ({platform_tag(unit)})",
        )
        _pip(offline, f"collecting rasm's dependencies for {unit.name}")
    for name in (rasm_wheel.name,):
        (dest / name).unlink(missing_ok=True)  # the rasm wheel itself lives one folder up
        (house / name).unlink(missing_ok=True)


def _dump(data: Any) -> str:
    yaml = YAML()
    yaml.default_flow_style = False
    out = io.StringIO()
    yaml.dump(data, out)
    return out.getvalue()


def _role(model: ArchitectureModel, unit: str) -> str:
    roles = {c.role in STAGES for c in model.components_on(unit)}
    return "all" if roles == {True, False} else "managing" if True in roles else "managed"


def _unit_config(model: ArchitectureModel, unit: ComputeUnit, manifest: Any) -> dict[str, Any]:
    role = _role(model, unit.name)
    interface = model.interface
    alone = all(model.deployment.get(c) == unit.name for c in model.components)
    transport = "local" if alone else str(interface.get("transport", manifest.transport))
    return {
        "unit": unit.name,
        "arch": unit.arch,
        "os": unit.os,
        "cpus": unit.cpus,
        "memory_mb": unit.memory_mb,
        "python": unit.python or f"{sys.version_info.major}.{sys.version_info.minor}",
        "role": role,
        "components": [c.name for c in model.components_on(unit.name)],
        "transport": transport,
        "knowledge": unit.knowledge or interface.get("knowledge", manifest.knowledge),
        "clock": unit.clock or interface.get("clock", "wall"),
        "binaries": f"01_Binaries/{platform_tag(unit)}",
        "app_module": app_module(manifest.name),
        "app_dist": app_module(manifest.name).replace("_", "-"),
        "checks": [
            {"kind": c.kind, "file": c.file} for c in model.checks if c.runs_on == unit.name
        ],
    }


def _node(model: ArchitectureModel, name: str, manifest: Any) -> tuple[str, dict[str, Any]]:
    c = model.components[name]
    layer = f"maple_k/{c.role}" if c.role in STAGES else "managed_system"
    ports = {}
    for port in c.ports.values():
        rows = [
            link
            for link in model.links
            if link.publisher == port.ref or port.ref in link.subscribers
        ]
        ports[port.name] = {
            "direction": port.direction,
            "message": port.message,
            "topics": [
                {
                    "topic": r.topic,
                    "protocol": r.protocol,
                    "qos": r.qos,
                    **({"rate": r.rate} if r.rate else {}),
                }
                for r in rows
            ],
        }
    implementation = (
        manifest.components.get(c.role) if c.role in STAGES else manifest.simulator
    )
    return f"02_Nodes/{layer}/{name}.yaml", {
        "node": name,
        "role": c.role,
        "layer": "MAPLE-K" if c.role in STAGES else "managed system",
        "unit": model.deployment.get(name),
        "implementation": implementation,
        "app_module": app_module(manifest.name),
        "description": c.description,
        "ports": ports,
        **({"produces": c.produces} if c.produces else {}),
    }


def _message_schema(message: Any) -> dict[str, Any]:
    kinds = {
        "float": "number",
        "int": "integer",
        "bool": "boolean",
        "str": "string",
        "json": "object",
    }
    properties = {}
    for name, spec in message.fields.items():
        prop: dict[str, Any] = {"type": kinds[spec["type"]]}
        if "min" in spec:
            prop["minimum"] = spec["min"]
        if "max" in spec:
            prop["maximum"] = spec["max"]
        properties[name] = prop
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": message.name,
        "description": message.description,
        "type": "object",
        "properties": properties,
    }


def _checklist(model: ArchitectureModel, manifest: Any) -> list[dict[str, Any]]:
    from rasm.lint import lint_paths
    from rasm.rules import load_rules, verify

    items = []
    folder = manifest.folder
    for check in model.checks:
        path = folder / check.file
        problems = lint_paths([str(path)]) if path.exists() else [f"{check.file} missing"]
        detail = "; ".join(problems[:3])
        if check.kind == "rules" and not problems:
            report = verify(load_rules(path).with_plan_fields(manifest.plan_fields))
            ok = report.consistent
            detail = "consistent (z3)" if ok else f"inconsistent: {report.reason()}"
            items.append(
                {
                    "what": f"rules `{check.file}`",
                    "where": check.runs_on,
                    "ok": ok,
                    "detail": detail,
                }
            )
        else:
            items.append(
                {
                    "what": f"{check.kind} `{check.file}` lint",
                    "where": check.runs_on,
                    "ok": not problems,
                    "detail": detail or "well-formed",
                }
            )
    items.append(
        {
            "what": "architecture model lint",
            "where": "-",
            "ok": True,
            "detail": "no problems" if model.source else "derived from app.yaml",
        }
    )
    return items


def package_app(
    app: str | Path,
    output: str | Path,
    *,
    key: bytes | None = None,
    dependencies: bool = True,
) -> PackageReport:
    """Build the deployment package of the app folder ``app`` into the zip ``output``."""
    from rasm.platform.manifest import load_manifest

    app = Path(app)
    if Path(output).is_dir():  # checked first: building the wheels takes a while
        raise PackageError(f"{output} is a folder: give the path of the zip to write (app.zip)")
    manifest = load_manifest(app)
    derived = not (manifest.folder / "model.yaml").is_file()
    if derived:
        model = model_from_manifest(manifest)
    else:
        model = load_model(manifest.folder / "model.yaml")
        problems = check_model(model)
        if problems:
            raise SourceErrors(problems)
    env = templates()
    created = datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    files: dict[str, bytes] = {}

    def put(name: str, data: str | bytes) -> None:
        files[name] = data.encode("utf-8") if isinstance(data, str) else data

    put(
        "00_Documentation/README.md",
        env.get_template("package/README.md.j2").render(
            model=model,
            manifest=manifest,
            created=created,
            derived=derived,
            rasm_version=metadata.version("rasm"),
        ),
    )
    put(
        "00_Documentation/architecture.md",
        env.get_template("package/architecture.md.j2").render(
            model=model,
            derived=derived,
            logical=logical_diagram(model),
            physical=physical_diagram(model),
            deployment=deployment_diagram(model),
        ),
    )
    put("00_Documentation/model.yaml", _dump(model_to_dict(model)))
    for name in model.components:
        path, node = _node(model, name, manifest)
        put(path, _dump(node))
    for message in model.messages.values():
        put(f"03_Messages/{message.name}.json", json.dumps(_message_schema(message), indent=2))
    if (manifest.folder / "messages.py").is_file():
        put("03_Messages/messages.py", (manifest.folder / "messages.py").read_bytes())
    for unit in model.units.values():
        put(f"04_Platform/{unit.name}.yaml", _dump(_unit_config(model, unit, manifest)))
    checks = {k: [c.file for c in model.checks if c.kind == k] for k in ("properties", "rules")}
    for action in ("install", "validate", "run", "stop"):
        put(
            f"05_Actions/{action}.sh",
            env.get_template(f"package/{action}.sh.j2").render(
                dist=app_module(manifest.name), **checks
            ),
        )
    items = _checklist(model, manifest)
    put(
        "06_Workflows/checklist.md",
        env.get_template("package/checklist.md.j2").render(
            model=model, items=items, created=created
        ),
    )
    put(
        "06_Workflows/workflows.yaml",
        env.get_template("package/workflows.yaml.j2").render(model=model),
    )
    wheels: list[str] = []
    with tempfile.TemporaryDirectory(prefix="rasm-package-") as tmp:
        work = Path(tmp)
        binaries = work / "01_Binaries"
        binaries.mkdir()
        built = _build_wheels(manifest.folder, manifest.name, binaries, work)
        if dependencies:
            rasm_wheel = next(w for w in built if w.name.startswith("rasm-"))
            done: set[str] = set()
            for unit in model.units.values():
                tag = platform_tag(unit)
                if tag not in done:
                    _download_dependencies(rasm_wheel, unit, binaries / tag)
                    done.add(tag)
        for wheel in sorted(binaries.rglob("*.whl")):
            name = f"01_Binaries/{wheel.relative_to(binaries).as_posix()}"
            put(name, wheel.read_bytes())
            wheels.append(name)
    listing = {
        "format": FORMAT,
        "app": manifest.name,
        "created": created,
        "rasm": metadata.version("rasm"),
        "units": sorted(model.units),
        "files": {name: digest(data) for name, data in sorted(files.items())},
        # checked against the zip's own sizes before deploy reads any file (no zip bomb)
        "sizes": {name: len(data) for name, data in sorted(files.items())},
    }
    raw = manifest_bytes(listing)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    partial = output.with_name(output.name + ".partial")
    try:
        with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            archive.writestr(MANIFEST, raw)
            if key is not None:
                archive.writestr(SIGNATURE, sign(raw, key) + "\n")
            for name, data in sorted(files.items()):
                info = zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = (0o755 if name.endswith(".sh") else 0o644) << 16
                archive.writestr(info, data)
        os.replace(partial, output)
    finally:
        partial.unlink(missing_ok=True)  # nothing half-written is left behind
    return PackageReport(
        output=output,
        app=manifest.name,
        files=len(files) + 1 + (key is not None),
        size=output.stat().st_size,
        wheels=wheels,
        units=sorted(model.units),
        signed=key is not None,
        derived_model=derived,
        checklist_failures=[i["what"] for i in items if not i["ok"]],
    )
