"""The ``rasm`` commands that read files and print a result (``run`` and ``monitor`` are in
:mod:`rasm.cli.live`, the parser in :mod:`rasm.cli.main`): a thin face over the Python API.

Each ``_cmd_*`` function parses nothing itself: it receives the parsed arguments, calls the API of
one sub-package and formats the result. Exit codes: 0 ok; 1 a property violated, in error or
not judged, rules inconsistent or lint errors; 2 bad input or usage, with ``file:line:col:
message`` where one exists.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable

from rasm.errors import RasmError, printable, read_utf8

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


class UsageError(RasmError):
    """Bad command-line usage that argparse cannot see (a missing file, a bad combination)."""


# --------------------------------------------------------------------------- statecharts


def _cmd_simulate(args: argparse.Namespace) -> int:
    import math

    from rasm.statechart.simulate import format_steps, read_events, simulate
    from rasm.times import format_seconds

    if args.until is not None and not (math.isfinite(args.until) and args.until >= 0):
        raise UsageError(f"--until must be a finite time in seconds, >= 0, not {args.until}")
    events = read_events(args.events) if args.events else []
    steps = simulate(args.chart, events, until=args.until)
    sys.stdout.write(format_steps(steps, args.format))
    failed = [step for step in steps if step.error]
    for step in failed:
        print(f"rasm: at time {format_seconds(step.time)}: {printable(step.error or '')}",
              file=sys.stderr)
    return EXIT_FAILED if failed else EXIT_OK


def _cmd_lint(args: argparse.Namespace) -> int:
    from rasm.lint import LintUsageError, lint_paths

    try:
        problems = lint_paths(args.paths)
    except LintUsageError as exc:
        print(f"rasm: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for problem in problems:
        print(printable(problem), file=sys.stdout)
    return EXIT_FAILED if problems else EXIT_OK


def _cmd_graph(args: argparse.Namespace) -> int:
    from rasm.statechart import export, load_statechart

    chart = load_statechart(args.chart)
    sys.stdout.write(export(chart, args.format))
    return EXIT_OK


# --------------------------------------------------------------------------- properties


def _cmd_check(args: argparse.Namespace) -> int:
    # exit 1 iff some property is violated, in error or not judged; inconclusive alone passes.
    # A trace or a recording is read record by record, never held whole (explaining the first
    # violations reads it once more).
    from rasm.properties.check import check_file, check_stream, format_json, format_text
    from rasm.properties.loader import load_specification

    if args.app is not None and args.topics is not None:
        raise UsageError("give a recording's topics by --app APP or by --topics MAP.yaml, not both")
    text = read_utf8(args.props)
    spec = load_specification(text, source=args.props)
    explain = args.format == "text" and not args.verdicts
    named = args.format == "text" or args.verdicts
    verdicts = sys.stdout if args.verdicts else None
    if _is_recording(args.trace) or args.trace.endswith(".mcap"):
        records, notes, damage = _recorded_or_mcap_records(args, spec.signals)
        report = check_stream(spec, records(), trace=args.trace,
                              again=records if explain else None,
                              named=named, verdicts=verdicts)
        for note in notes():
            print(f"rasm: note: {args.trace}: {note}", file=sys.stderr)
        report.note_damage(damage())
        if not explain:  # the text report lists the damage itself
            for lost in report.damage:
                print(f"rasm: damaged: {printable(lost.describe())}", file=sys.stderr)
        if report.damage and not args.allow_damaged:
            print(f"rasm: {args.trace} is damaged: a verdict that depended on what was lost is "
                  "not 'satisfied', and the check fails (--allow-damaged accepts verdicts on "
                  "what could be read)", file=sys.stderr)
    elif args.app is not None or args.topics is not None:
        raise UsageError(
            f"{args.trace}: --app and --topics map a rosbag2 recording's topics to signals; a "
            "JSONL trace names its signals itself"
        )
    else:
        report = check_file(spec, args.trace, explain_violations=explain, named=named,
                            verdicts=verdicts)
    if not args.verdicts:
        sys.stdout.write(format_json(report) if args.format == "json" else format_text(report))
    refused = report.depends_on_damage and not args.allow_damaged
    return EXIT_FAILED if report.failed or refused else EXIT_OK


def _is_recording(path: str) -> bool:
    """A rosbag2 recording (a bag folder, a .db3 file, an MCAP file that is no rasm trace)."""
    from pathlib import Path

    target = Path(path)
    if target.is_dir() or target.suffix == ".db3":
        return True
    if target.suffix != ".mcap":
        return False
    from rasm.trace_mcap import is_mcap_trace

    return not is_mcap_trace(target)


def _recorded_or_mcap_records(
    args: argparse.Namespace, signals: dict[str, str]
) -> tuple[
    Callable[[], Iterable[tuple[float, dict]]], Callable[[], list[str]], Callable[[], list]
]:
    """How to read the records of a rasm MCAP trace, or of a rosbag2 recording with the probes
    of --app or --topics, each call reading them anew one by one; what the first whole
    reading left out (notes for standard error); and what could not be read (damage)."""
    if not _is_recording(args.trace):
        if args.app is not None or args.topics is not None:
            raise UsageError(
                f"{args.trace}: --app and --topics map a rosbag2 recording's topics to "
                "signals; a rasm trace names its signals itself"
            )
        from rasm.trace import parse_records
        from rasm.trace_mcap import McapTrace

        trace = McapTrace(args.trace)

        def trace_records() -> Iterable[tuple[float, dict]]:
            return parse_records(trace, signals, source=args.trace)

        return trace_records, list, lambda: trace.damage
    from rasm.platform.replay import recorded_trace

    if args.app is not None:
        from rasm.platform.manifest import load_manifest

        manifest = load_manifest(args.app)
        probes, store = manifest.probes, manifest.types
    elif args.topics is not None:
        from rasm.platform.manifest import load_topic_map
        from rasm.ros2 import TypeStore, recorded_types

        # a topic map may name the types the recording itself defines
        known = TypeStore()
        recorded_types(args.trace, known)
        probes, store = load_topic_map(args.topics, known)
    else:
        raise UsageError(
            f"{args.trace} is a rosbag2 recording: say which topics give which signals, with "
            "--app APP (its probes) or --topics MAP.yaml (a 'probes:' list as in app.yaml)"
        )
    recorded = recorded_trace(args.trace, probes, store, signals)
    return lambda: recorded, recorded.notes, lambda: recorded.damage


def _cmd_verify_rules(args: argparse.Namespace) -> int:
    from rasm.rules import format_json, format_text, load_rules, verify
    from rasm.rules.against import check_against
    from rasm.rules.fallback import prove_fixed_plan

    paths, fallback, plan_fields = _rules_of(args.rules)
    failed = False
    for path in paths:
        rules = load_rules(path).with_plan_fields(plan_fields)
        report = verify(rules)
        if args.against:
            report.against = check_against(rules, args.against)
        if fallback is not None:
            report.fallback = fallback
            report.fallback_proof = prove_fixed_plan(rules, fallback)
        sys.stdout.write(format_json(report) if args.format == "json" else format_text(report))
        failed |= not report.consistent or report.admits_violations or report.fallback_refused
    return EXIT_FAILED if failed else EXIT_OK


def _is_manifest(path) -> bool:
    """Whether a YAML file is an app manifest (it names components) rather than rules."""
    from rasm.errors import RasmError
    from rasm.yamltext import load_yaml

    if path.name == "app.yaml":
        return True
    try:
        data = load_yaml(path.read_text(encoding="utf-8"), str(path)).data
    except (OSError, UnicodeDecodeError, RasmError):
        return False  # load_rules reports what is wrong with it
    return isinstance(data, dict) and "components" in data and "variables" not in data


def _rules_of(target: str) -> tuple[list, dict | None, list[str]]:
    """``verify-rules`` of a rules file, or of an app (its folder or app.yaml): every rules file
    of the app, its fallback actions as one plan to prove legitimate in every context, and its
    plan fields (``components.plan.produces``)."""
    from pathlib import Path

    from rasm.platform.manifest import load_manifest

    path = Path(target)
    if not (path.is_dir() or _is_manifest(path)):
        return [path], None, []
    manifest = load_manifest(path)
    fallback = manifest.fallback.values if manifest.fallback is not None else None
    return list(manifest.rules), fallback, manifest.plan_fields


def _cmd_report(args: argparse.Namespace) -> int:
    from collections import Counter

    from rasm.properties.check import STATE_ORDER
    from rasm.report import write_report

    # --props FILE.rv (repeatable) and --no-platform-props, where the parser offers them
    props = getattr(args, "props", None) or []
    model = write_report(
        args.trace,
        args.output,
        props,
        platform_props=getattr(args, "platform_props", True),
        app=getattr(args, "app", None),
    )
    checked = model["properties"]["timelines"]
    states = Counter(t["verdict"] for t in checked)
    print(
        f"rasm: {args.output}: {model['records']} records, {len(model['adaptations'])} "
        f"adaptations, {len(checked)} properties ("
        + (", ".join(f"{states[state]} {state}" for state in STATE_ORDER if states[state])
           or "none checked")
        + ")",
        file=sys.stderr,
    )
    for note in model["missing"]:
        print(f"rasm: note: {note}", file=sys.stderr)
    return EXIT_OK


def _cmd_new(args: argparse.Namespace) -> int:
    from rasm.workflow import new_app

    result = new_app(args.name, args.model)
    for path in result.written:
        print(f"wrote {path}")
    for path in result.kept:
        print(f"kept  {path} (yours: not regenerated)")
    for path, regions in result.orphans.items():
        for region in regions:
            print(
                f"rasm: {path}:{region.line}: region {region.id} could not be kept (its component "
                f"left the model); saved to {result.folder}/.rasm-orphans/{path.name}.txt",
                file=sys.stderr,
            )
    return EXIT_OK


def _cmd_package(args: argparse.Namespace) -> int:
    import os

    from rasm.workflow import configured_key, package_app

    key = configured_key(getattr(args, "key_file", None))
    bundle = not getattr(args, "no_deps", False) and os.environ.get("RASM_PACKAGE_NO_DEPS") != "1"
    report = package_app(args.app, args.output, key=key, dependencies=bundle)
    signed = "signed (HMAC-SHA256)" if report.signed else "unsigned (no key configured)"
    print(
        f"{report.output}: {report.app}, {report.files} files, {len(report.wheels)} wheels, "
        f"{report.size / 1e6:.1f} MB, units: {', '.join(report.units)}; {signed}"
    )
    if report.derived_model:
        print("no model.yaml: documented a minimal model derived from app.yaml")
    for item in report.checklist_failures:
        print(f"rasm: checklist item failed: {item} (see 06_Workflows/checklist.md)",
              file=sys.stderr)
    return EXIT_FAILED if report.checklist_failures else EXIT_OK


def _cmd_deploy(args: argparse.Namespace) -> int:
    from rasm.workflow import configured_key, deploy_package

    key = configured_key(getattr(args, "key_file", None))
    report = deploy_package(
        args.package, args.unit, args.target, key=key, start=getattr(args, "start", False)
    )
    print(f"{args.package}: {report.files} files verified; {report.signature}")
    for step in report.steps:
        print(f"{step.action}: {'ok' if step.ok else f'failed (exit {step.returncode})'}")
        if not step.ok:
            sys.stderr.write(step.output)
    if report.ok:
        print(f"unit {report.unit} (role {report.role}) deployed in {report.target}")
    return EXIT_OK if report.ok else EXIT_FAILED
