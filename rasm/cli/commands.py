"""The ``rasm`` commands that read files and print a result (``run`` and ``monitor`` are in
:mod:`rasm.cli.live`, the parser in :mod:`rasm.cli.main`): a thin face over the Python API.

Each ``_cmd_*`` function parses nothing itself: it receives the parsed arguments, calls the API of
one sub-package and formats the result. Exit codes: 0 ok; 1 a property violated, in error or
not judged, rules inconsistent or lint errors; 2 bad input or usage, with ``file:line:col:
message`` where one exists.
"""

from __future__ import annotations

import argparse
import json
import sys

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
    # violations reads it once more). Several recordings, or a large trace cut into parts, are
    # checked in --jobs processes or on a --cluster (rasm.scale); a recording that cannot be
    # checked is reported by name while the others are (exit 2).
    from rasm.properties.check import format_json, format_text
    from rasm.scale import Job, check_recording
    from rasm.scale.recordings import spec_of

    if args.app is not None and args.topics is not None:
        raise UsageError("give a recording's topics by --app APP or by --topics MAP.yaml, not both")
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs must be 1 or more, not {args.jobs}")
    if args.cluster is not None and args.jobs is not None:
        raise UsageError("--jobs sets the local processes; a --cluster has its own workers")
    if args.robustness and (args.cluster is not None or (args.jobs or 1) > 1
                            or args.part_size is not None):
        # a minimum over the records, and values across a cut: one pass per recording
        raise UsageError("--robustness is computed in one pass over each recording: "
                         "not with --jobs above 1, --part-size or --cluster")
    if args.verdicts and len(args.recordings) > 1:
        raise UsageError("--verdicts prints every verdict of one recording: give one")
    text = read_utf8(args.props)
    explain = args.format == "text" and not args.verdicts
    named = args.format == "text" or args.verdicts
    app, topics = args.app, args.topics
    if args.cluster is not None:  # the workers have working folders of their own
        import os

        args.recordings = [os.path.abspath(p) for p in args.recordings]
        app = os.path.abspath(app) if app is not None else None
        topics = os.path.abspath(topics) if topics is not None else None
    job = Job(args.props, text, app, topics, explain, named, args.robustness)
    spec_of(job)  # a bad property file is refused first (and loaded once: the job's)
    if args.verdicts:
        checked = check_recording(job, args.recordings[0], verdicts=sys.stdout)
        _notes(checked, explain)
        return _check_status(checked.report, args)
    outcomes = _check_many(job, args)
    if len(outcomes) == 1 and outcomes[0].failed:
        for message in outcomes[0].failed:
            print(f"rasm: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if len(outcomes) == 1:
        checked = outcomes[0].checked
        _notes(checked, explain)
        report = checked.report
        sys.stdout.write(format_json(report) if args.format == "json" else format_text(report))
        return _check_status(report, args)
    return _report_many(outcomes, args, explain)


def _check_many(job, args: argparse.Namespace) -> list:
    """Every recording checked: here, in local processes, or on the cluster."""
    import os

    from rasm.scale import DaskCluster, InProcess, Processes, check_many, is_trace, plan_parts
    from rasm.scale.many import cores

    paths = args.recordings
    if args.cluster is not None:
        engine = DaskCluster(args.cluster)
        jobs = sum(engine.client.nthreads().values()) or 1
    else:
        jobs = args.jobs or (1 if args.robustness else cores())
        sizes = [os.path.getsize(p) if is_trace(p) and os.path.isfile(p) else 0 for p in paths]
        alone = len(paths) == 1 and plan_parts(sizes, jobs, args.part_size) == [1]
        engine = InProcess() if jobs == 1 or alone else Processes(jobs)
    try:
        with _progress(not isinstance(engine, InProcess)) as progress:
            return check_many(job, paths, engine=engine, jobs=jobs, part_size=args.part_size,
                              progress=progress)
    finally:
        engine.close()


def _progress(shown: bool):
    """A progress bar on standard error (a terminal), for checks that run in workers."""
    import contextlib

    if not (shown and sys.stderr.isatty()):
        return contextlib.nullcontext(None)
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

    @contextlib.contextmanager
    def bar():
        with Progress("checking", BarColumn(), DownloadColumn(), TimeRemainingColumn(),
                      console=Console(stderr=True), transient=True) as shown_bar:
            task = shown_bar.add_task("check", total=None)

            def update(done: int, total: int) -> None:
                shown_bar.update(task, completed=done, total=total)

            yield update

    return bar()


def _notes(checked, explain: bool) -> None:
    """What reading a recording left out, and what it lost, on standard error."""
    for note in checked.notes:
        print(f"rasm: note: {note}", file=sys.stderr)
    if not explain:  # the text report lists the damage itself
        for lost in checked.report.damage:
            print(f"rasm: damaged: {printable(lost.describe())}", file=sys.stderr)


def _check_status(report, args: argparse.Namespace) -> int:
    refused = report.depends_on_damage and not args.allow_damaged
    if refused:
        print(f"rasm: {report.trace} is damaged: a verdict that depended on what was lost is "
              "not 'satisfied', and the check fails (--allow-damaged accepts verdicts on "
              "what could be read)", file=sys.stderr)
    return EXIT_FAILED if report.failed or refused else EXIT_OK


def _report_many(outcomes: list, args: argparse.Namespace, explain: bool) -> int:
    """Each recording's report, in the order given, and the total; exit 2 when one could not
    be checked, else 1 when one fails."""
    import json

    from rasm.properties.check import format_text, json_object

    status = {}
    entries = []
    for outcome in outcomes:
        sys.stdout.flush()  # each recording's lines where they belong, stdout and stderr alike
        if outcome.failed:
            for message in outcome.failed:
                print(f"rasm: {message}", file=sys.stderr)
            status[outcome.recording] = "not checked"
            entries.append({"recording": outcome.recording, "error": list(outcome.failed)})
            continue
        _notes(outcome.checked, explain)
        report = outcome.report
        failed = _check_status(report, args) != EXIT_OK
        status[outcome.recording] = "fails" if failed else "passes"
        if args.format == "json":
            entries.append({"recording": outcome.recording, **json_object(report)})
        else:
            sys.stdout.write(format_text(report))
    counts = {word: sum(1 for s in status.values() if s == word)
              for word in ("passes", "fails", "not checked")}
    records = sum(o.report.records for o in outcomes if o.report is not None)
    if args.format == "json":
        total = {"recordings": len(outcomes), "records": records, "passed": counts["passes"],
                 "failed": counts["fails"], "not_checked": counts["not checked"]}
        sys.stdout.write(json.dumps({"recordings": entries, "total": total}) + "\n")
    else:
        parts = [f"{counts['fails']} fail", f"{counts['passes']} pass"]
        if counts["not checked"]:
            parts.append(f"{counts['not checked']} not checked")
        print(f"{len(outcomes)} recordings, {records} records: {', '.join(parts)}")
    if counts["not checked"]:
        return EXIT_BAD_INPUT
    return EXIT_FAILED if counts["fails"] else EXIT_OK


def _cmd_verify(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rasm.verify import verify_chart
    from rasm.verify.text import format_verification

    if args.max_states < 1:
        raise UsageError(f"--max-states must be at least 1, not {args.max_states}")
    target = Path(args.target)
    if not target.exists():
        raise UsageError(f"{args.target}: no such chart or app")
    if target.is_dir() or target.name == "app.yaml" or _is_manifest(target):
        from rasm.verify.app import verify_app

        if args.env or args.properties:
            raise UsageError(
                "rasm verify APP explores what the app's own manifest allows: --env and "
                "--properties apply to one chart (rasm verify CHART.yaml)"
            )
        result = verify_app(target, max_states=args.max_states)
    else:
        result = verify_chart(
            target, environment=args.env, properties=args.properties, max_states=args.max_states
        )
    if args.counterexamples:
        _write_counterexamples(result, Path(args.counterexamples))
    if args.format == "json":
        sys.stdout.write(json.dumps(result.as_dict()) + "\n")
    else:
        sys.stdout.write(format_verification(result))
    return result.exit_code


def _is_manifest(path) -> bool:
    """Whether a YAML file is an app manifest (it names components), not a chart."""
    try:
        head = path.read_text(encoding="utf-8", errors="replace")[:20_000]
    except OSError:
        return False
    return "\ncomponents:" in f"\n{head}" and "statechart:" not in head


def _write_counterexamples(result, folder) -> None:
    """One events file per violated property and per problem with a path, named after it."""
    folder.mkdir(parents=True, exist_ok=True)
    numbered: dict[str, int] = {}
    named = [(f"property-{p.name}", p.counterexample) for p in result.properties]
    named += [(f.kind.replace(" ", "-"), f.counterexample) for f in result.problems]
    for name, cex in named:
        if cex is None or not cex.moves and name.startswith("unreachable"):
            continue
        numbered[name] = numbered.get(name, 0) + 1
        suffix = "" if numbered[name] == 1 else f"-{numbered[name]}"
        (folder / f"{name}{suffix}.jsonl").write_text(cex.jsonl(), encoding="utf-8")


def _cmd_verify_rules(args: argparse.Namespace) -> int:
    from rasm.rules import format_json, format_text, load_rules, verify
    from rasm.rules.against import check_against
    from rasm.rules.fixed_plan import prove_fixed_plan

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
