"""``rasm new``: an application folder generated from an architecture model.

The files come from Jinja2 templates under ``templates/app``. Regenerating after a model change
keeps every engineer's region (``# >>> rasm:user ID`` … ``# <<< rasm:user ID``); a region whose
component left the model is saved under ``.rasm-orphans/`` and reported. Property and rule files,
stage and modes charts, tests and the model itself are created once and never overwritten.
"""

from __future__ import annotations

import io
import shutil
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from jinja2 import Environment, FileSystemLoader, StrictUndefined
from ruamel.yaml import YAML
from ruamel.yaml.scalarstring import LiteralScalarString

from rasm.errors import Location, RasmError, SourceError, SourceErrors
from rasm.loop import STAGES
from rasm.workflow.checks import check_model, produced_signals
from rasm.workflow.derive import app_config, effectors, probes, publications
from rasm.workflow.model import MANAGED_ROLES, ArchitectureModel, load_model
from rasm.workflow.regions import Region, RegionError, merge

__all__ = ["GenerateError", "Generated", "generate_app", "new_app", "templates"]

TEMPLATES = Path(__file__).with_name("templates")
ORPHANS = ".rasm-orphans"
_PYTYPES = {"float": "float", "int": "int", "bool": "bool", "str": "str", "json": "Any"}


class GenerateError(RasmError):
    """The target folder cannot be (re)generated (not a generated app, broken markers)."""


@dataclass
class Generated:
    """What ``rasm new`` did: files written, files left alone, regions it could not keep."""

    folder: Path
    written: list[Path] = field(default_factory=list)
    kept: list[Path] = field(default_factory=list)
    orphans: dict[Path, list[Region]] = field(default_factory=dict)


def templates() -> Environment:
    """The Jinja2 environment over ``rasm/workflow/templates`` (strict: unknown names fail)."""
    env = Environment(
        loader=FileSystemLoader(str(TEMPLATES)),
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        undefined=StrictUndefined,
        autoescape=False,
    )
    env.filters["pytype"] = lambda t: _PYTYPES[t]
    env.filters["oneline"] = _oneline
    env.filters["printable"] = _printable
    env.filters["stem"] = lambda path: Path(path).stem
    env.filters["wrap"] = _wrap
    env.filters["pydefault"] = _default
    return env


def _oneline(text: str) -> str:
    """Free text made safe for one line of a docstring or a comment."""
    return " ".join(str(text).split()).replace("\\", "/").replace('"', "'")


def _printable(text: str) -> str:
    """Free text without the characters a YAML block or comment cannot hold (controls, BOMs,
    line separators)."""
    return "".join(c if c.isprintable() else " " for c in str(text))


def _wrap(text: str, indent: int) -> str:
    """Free text as docstring lines of at most 96 characters, indented by ``indent``."""
    return textwrap.fill(
        _oneline(text), width=96, initial_indent="", subsequent_indent=" " * indent
    )


def _default(spec: dict[str, Any]) -> str:
    kind = spec["type"]
    if kind == "json":
        return "field(default_factory=dict)"
    if kind == "bool":
        return "False"
    if kind == "str":
        return '""'
    value: float = 0
    if spec.get("min") is not None and value < spec["min"]:
        value = spec["min"]
    if spec.get("max") is not None and value > spec["max"]:
        value = spec["max"]
    if kind == "int":
        return repr(int(value)) if float(value).is_integer() else repr(int(value) + 1)
    return repr(float(value))


def _yaml(data: Any) -> str:
    if isinstance(data, dict) and "\n" in str(data.get("description", "")).strip():
        data = {**data, "description": LiteralScalarString(str(data["description"]))}
    yaml = YAML()
    yaml.default_flow_style = False
    yaml.indent(mapping=2, sequence=4, offset=2)
    out = io.StringIO()
    yaml.dump(data, out)
    return out.getvalue().rstrip("\n")


def _rules_stub(model: ArchitectureModel) -> str:
    variables: dict[str, Any] = {}
    rules: list[dict[str, str]] = []
    for effector in effectors(model):
        message = model.messages.get(effector.message)
        for name, spec in (message.fields if message else {}).items():
            if spec["type"] in ("float", "int"):
                var = {"type": "real" if spec["type"] == "float" else "int"}
                for bound in ("min", "max"):
                    if spec.get(bound) is not None:
                        var[bound] = spec[bound]
                variables[name] = var
                if "min" in var and "max" in var:
                    rules.append(
                        {
                            "name": f"{name}_in_range",
                            "require": f"{name} >= {var['min']} and {name} <= {var['max']}",
                        }
                    )
            elif spec["type"] == "bool":
                variables[name] = {"type": "bool"}
    return (
        _yaml({"variables": variables or {}, "rules": rules})
        if variables or rules
        else ("variables: {}\nrules: []")
    )


_STAGE_IMPORTS = {
    "monitor": ("StageContext",),
    "analyse": ("Anomaly", "StageContext"),
    "plan": ("Plan", "StageContext"),
    "legitimate": ("StageContext",),
    "execute": ("Action", "StageContext"),
}


def _context(model: ArchitectureModel) -> dict[str, Any]:
    stages = [c for c in (model.stage(s) for s in STAGES) if c is not None]
    maple = [c for c in stages if c.chart is None]  # the stages written in Python
    monitor = model.stage("monitor")
    managed = [c for c in model.components.values() if c.role in MANAGED_ROLES]
    signals = sorted(
        key
        for message in probes(model).values()
        for key in (model.messages[message].fields if message in model.messages else {})
    )
    rule_variables = sorted(
        {k for e in effectors(model) for k in model.messages[e.message].fields}
        if all(e.message in model.messages for e in effectors(model))
        else set()
    )
    managed_names = {c.name for c in managed}
    messages = list(model.messages.values())
    return {
        "model": model,
        "maple": maple,
        "charts": [c for c in stages if c.chart is not None],
        "produced_by_monitor": sorted(monitor.produces) if monitor else [],
        "rasm_imports": sorted({name for c in maple for name in _STAGE_IMPORTS[c.role]}),
        "managed": managed,
        "signals": signals,
        "produced": produced_signals(model),
        "effectors": effectors(model),
        "sim_effectors": [e for e in effectors(model) if e.component in managed_names],
        "publications": publications(model),
        "rule_variables": rule_variables,
        "messages": messages,
        "needs_field": any(f["type"] == "json" for m in messages for f in m.fields.values()),
        "config_yaml": _yaml(app_config(model)),
    }


def generate_app(model: ArchitectureModel, folder: str | Path) -> Generated:
    """Write (or regenerate) the application for ``model`` into ``folder``."""
    folder = Path(folder)
    env = templates()
    ctx = _context(model)
    result = Generated(folder)
    owned = {
        "app.yaml": "app/app.yaml.j2",
        "components.py": "app/components.py.j2",
        "messages.py": "app/messages.py.j2",
        "README.md": "app/README.md.j2",
    }
    once: dict[str, tuple[str, dict[str, Any]]] = {
        f"tests/test_{model.name.replace('-', '_')}.py": ("app/test_app.py.j2", {}),
    }
    for check in model.checks:
        template = "app/properties.rv.j2" if check.kind == "properties" else "app/rules.yaml.j2"
        once[check.file] = (template, {"check": check, "rules_yaml": _rules_stub(model)})
    for component in ctx["charts"]:
        once[component.chart] = ("app/stage_chart.yaml.j2", {"component": component})
    if model.modes is not None:
        once[model.modes.chart] = ("app/modes_chart.yaml.j2", {"modes": model.modes})
    rendered: list[tuple[str, Path, str, list[Region]]] = []
    for name, template in owned.items():  # merge everything first: broken markers write nothing
        path = folder / name
        fresh = env.get_template(template).render(**ctx)
        old = path.read_text(encoding="utf-8") if path.is_file() else None
        try:
            text, orphans = merge(fresh, old, str(path))
        except RegionError as exc:
            raise GenerateError(f"cannot regenerate {path}: {exc}") from None
        rendered.append((name, path, text, [r for r in orphans if r.written]))
    folder.mkdir(parents=True, exist_ok=True)
    for name, path, text, lost in rendered:
        path.write_text(text, encoding="utf-8")
        result.written.append(path)
        if lost:
            result.orphans[path] = lost
            _save_orphans(folder, name, lost)
    for name, (template, extra) in once.items():
        path = folder / name
        if path.exists():
            result.kept.append(path)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        check = extra.get("check")
        if check is not None and check.text is not None:
            text = check.text
        else:
            text = env.get_template(template).render(**ctx, **extra)
        path.write_text(text, encoding="utf-8")
        result.written.append(path)
    return result


def _save_orphans(folder: Path, name: str, regions: list[Region]) -> None:
    target = folder / ORPHANS / f"{name}.txt"
    target.parent.mkdir(parents=True, exist_ok=True)
    blocks = [
        f"# region {r.id} (was at line {r.line}); its component left the model\n"
        + "\n".join(r.body)
        + "\n"
        for r in regions
    ]
    with target.open("a", encoding="utf-8") as handle:
        handle.write("\n".join(blocks))


def _starter_model(name: str) -> str:
    from rasm.workflow.derive import host_arch

    return templates().get_template("app/model.yaml.j2").render(name=name, arch=host_arch())


def new_app(target: str | Path, model_file: str | Path | None = None) -> Generated:
    """``rasm new``: create or regenerate the app folder ``target``.

    With ``model_file`` the model is copied to ``target/model.yaml`` first; without it an
    existing ``target/model.yaml`` is used, or a starter model (one managed plant, the five
    stages, one compute unit) is written. The model is linted first: problems raise
    :class:`SourceErrors` with their positions and nothing is written.
    """
    folder = Path(target)
    own_model = folder / "model.yaml"
    if folder.exists() and not folder.is_dir():
        raise GenerateError(f"{folder} exists and is not a folder")
    if folder.is_dir() and any(folder.iterdir()) and not own_model.is_file():
        raise GenerateError(
            f"{folder} exists and was not generated by rasm new (no model.yaml): "
            "choose a new folder"
        )
    parent = folder.resolve().parent
    in_an_app = (parent / "model.yaml").is_file() and (parent / "app.yaml").is_file()
    if not folder.exists() and in_an_app:
        # typing the regenerate command inside the app folder would nest a second app in it
        raise GenerateError(
            f"{parent} is an app folder (it holds model.yaml and app.yaml): rasm new will not "
            f"create the app {folder.name} inside it. To regenerate this app, run `rasm new .` "
            f"here (or `rasm new {parent.name}` from its parent folder)"
        )
    if model_file is not None:
        source = Path(model_file)
        model = load_model(source)
        _raise_problems(model)
        folder.mkdir(parents=True, exist_ok=True)
        if not own_model.exists() or not own_model.samefile(source):
            shutil.copyfile(source, own_model)
        model.file = own_model
    elif own_model.is_file():
        model = load_model(own_model)
        _raise_problems(model)
    else:
        name = folder.resolve().name
        if not name[:1].isalpha():
            raise SourceError(
                f"'{name}' cannot name an app (start with a letter)", Location(str(folder))
            )
        folder.mkdir(parents=True, exist_ok=True)
        own_model.write_text(_starter_model(_app_name(name)), encoding="utf-8")
        model = load_model(own_model)
        _raise_problems(model)
    return generate_app(model, folder)


def _app_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in name)


def _raise_problems(model: ArchitectureModel) -> None:
    problems = check_model(model)
    if problems:
        raise SourceErrors(problems)
