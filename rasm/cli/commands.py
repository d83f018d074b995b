"""The ``rasm`` command line: a thin face over the Python API.

Each ``_cmd_*`` function parses nothing itself: it receives the parsed arguments, calls the API of
one sub-package and formats the result. Exit codes: 0 ok; 1 a property violated, in error or
not judged, rules inconsistent or lint errors; 2 bad input or usage, with ``file:line:col:
message`` where one exists.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import TYPE_CHECKING

import rasm
from rasm.errors import RasmError, SourceErrors, printable, raise_interrupted, read_utf8

if TYPE_CHECKING:
    from rasm.platform.platform import Platform

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


class UsageError(RasmError):
    """Bad command-line usage that argparse cannot see (a missing file, a bad combination)."""


def _open_output(path: str | None):
    if path is None or path == "-":
        return sys.stdout
    return open(path, "w", encoding="utf-8")


# --------------------------------------------------------------------------- statecharts


def _cmd_simulate(args: argparse.Namespace) -> int:
    import math

    from rasm.statechart.simulate import format_steps, read_events, simulate

    if args.until is not None and not (math.isfinite(args.until) and args.until >= 0):
        raise UsageError(f"--until must be a finite time in seconds, >= 0, not {args.until}")
    events = read_events(args.events) if args.events else []
    steps = simulate(args.chart, events, until=args.until)
    sys.stdout.write(format_steps(steps, args.format))
    failed = [step for step in steps if step.error]
    for step in failed:
        print(f"rasm: at time {step.time:g}: {printable(step.error or '')}", file=sys.stderr)
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
        records, notes = _recorded_or_mcap_records(args, spec.signals)
        report = check_stream(spec, records(), trace=args.trace,
                              again=records if explain else None,
                              named=named, verdicts=verdicts)
        for note in notes():
            print(f"rasm: note: {args.trace}: {note}", file=sys.stderr)
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
    return EXIT_FAILED if report.failed else EXIT_OK


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
) -> tuple[Callable[[], Iterable[tuple[float, dict]]], Callable[[], list[str]]]:
    """How to read the records of a rasm MCAP trace, or of a rosbag2 recording with the probes
    of --app or --topics, each call reading them anew one by one; and what the first whole
    reading left out (notes for standard error)."""
    if not _is_recording(args.trace):
        if args.app is not None or args.topics is not None:
            raise UsageError(
                f"{args.trace}: --app and --topics map a rosbag2 recording's topics to "
                "signals; a rasm trace names its signals itself"
            )
        from rasm.trace import parse_records
        from rasm.trace_mcap import read_mcap_trace

        def trace_records() -> Iterable[tuple[float, dict]]:
            return parse_records(read_mcap_trace(args.trace), signals, source=args.trace)

        return trace_records, list
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
    return lambda: recorded, recorded.notes


def _cmd_monitor(args: argparse.Namespace) -> int:
    # runs until Ctrl-C / SIGTERM (or --duration S); exit 1 iff some property was violated, in
    # error or never judged.
    # With RASM_UPDATE_KEY (hex) set, HMAC-signed {"spec": …} on rasm/update/properties, bound
    # to the epoch this process announces on rasm/presence/monitor-<pid>, replace the properties
    # at run time (the public checker's unsigned `reconfig`, made safe).
    import math
    import os
    import signal
    import threading

    from rasm.attach import Attachment, load_topic_map
    from rasm.comm import open_transport
    from rasm.comm.url import credentials_from_env
    from rasm.properties import load_specification

    duration = getattr(args, "duration", None)
    if duration is not None and not 0 < duration < math.inf:
        raise UsageError(f"--duration must be a positive number of seconds, got {duration}")
    text = read_utf8(args.props)
    signals = list(load_specification(text, source=args.props).signals)
    topics = load_topic_map(args.topics, signals) if args.topics else None
    transport = open_transport(args.transport, **credentials_from_env(args.transport))
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stop.set())

    def show(verdict) -> None:
        if verdict.error is not None:
            print(f"error {verdict.property} at t={verdict.time:g}: {verdict.error}", flush=True)
        elif verdict.value is False:
            print(f"violated {verdict.property} at t={verdict.time:g}", flush=True)

    attachment = Attachment(
        text, transport, source=args.props, topics=topics, on_verdict=show
    )
    key_text = os.environ.get("RASM_UPDATE_KEY")
    try:
        key = bytes.fromhex(key_text) if key_text else None
    except ValueError:
        raise UsageError("RASM_UPDATE_KEY must be the signing key in hexadecimal") from None
    transport.connect()
    presence = None
    try:
        attachment.start()
        if key:
            from rasm.comm import Presence, UpdateReceiver

            receiver = UpdateReceiver(transport, key, properties=attachment.replace).start()
            # senders bind updates to the epoch announced here (a replayed one is refused)
            presence = Presence(
                transport, f"monitor-{os.getpid()}", role="monitor", info={"epoch": receiver.epoch}
            ).start()
        print(
            f"rasm monitor: {len(attachment.monitor.properties)} properties on "
            f"{len(attachment.subscribed_topics)} topic(s) of {args.transport}; "
            "verdicts on the topics named after the properties; Ctrl-C stops",
            file=sys.stderr,
            flush=True,
        )
        try:
            stop.wait(duration)
        except KeyboardInterrupt:
            pass
        summary = attachment.stop()
    finally:
        attachment.stop()
        if presence is not None:
            presence.stop()
        transport.close()
    sys.stdout.write(summary.format())
    return EXIT_FAILED if summary.failed else EXIT_OK


# --------------------------------------------------------------------------- rules


def _cmd_verify_rules(args: argparse.Namespace) -> int:
    from rasm.rules import format_json, format_text, load_rules, verify
    from rasm.rules.against import check_against
    from rasm.rules.fallback import prove_fixed_plan

    paths, fallback = _rules_of(args.rules)
    failed = False
    for path in paths:
        rules = load_rules(path)
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


def _rules_of(target: str) -> tuple[list, dict | None]:
    """``verify-rules`` of a rules file, or of an app (its folder or app.yaml): every rules file
    of the app, and its fallback actions as one plan to prove legitimate in every context."""
    from pathlib import Path

    from rasm.platform.manifest import load_manifest

    path = Path(target)
    if not (path.is_dir() or _is_manifest(path)):
        return [path], None
    manifest = load_manifest(path)
    fallback = manifest.fallback.values if manifest.fallback is not None else None
    return list(manifest.rules), fallback


# --------------------------------------------------------------------------- platform


def _read_scenario(text: str) -> dict:
    """``--scenario``: JSON text, or a JSON/YAML file."""
    from pathlib import Path

    from rasm.errors import Location, SourceError
    from rasm.jsontext import JsonProblem, parse_json
    from rasm.yamltext import load_yaml, plain

    path = Path(text)
    try:
        is_file = not text.lstrip().startswith("{") and path.is_file()
    except (OSError, ValueError):  # a name too long for a file, a NUL byte: not a file
        is_file = False
    if is_file:
        data = plain(load_yaml(read_utf8(path), str(path)).data)
        where = str(path)
    else:
        try:
            data = parse_json(text)
        except JsonProblem as exc:
            raise SourceError(f"--scenario (not a file): {exc.message}",
                              Location("--scenario", 1, exc.column)) from None
        where = "--scenario"
    if not isinstance(data, dict):
        raise SourceError("a scenario is a mapping, e.g. {\"openings\": [[5, 10]]}",
                          Location(where, 1, 1))
    return data


@contextlib.contextmanager
def _stop_on_signals(platform: Platform) -> Iterator[None]:
    """SIGTERM and SIGINT stop the run in order (``Platform.request_stop``): knowledge
    persisted, trace closed, summary printed, the exit code of a normal end. A second one
    during that stop aborts at once (exit 130). The handlers only set flags: printing from a
    handler could interrupt a write to the same stream."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread may handle signals
        return

    def abort(signum, frame) -> None:
        raise KeyboardInterrupt

    def stop(signum, frame) -> None:
        platform.request_stop(signal.Signals(signum).name)
        for kind in (signal.SIGTERM, signal.SIGINT):
            signal.signal(kind, abort)

    previous = {kind: signal.signal(kind, stop) for kind in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for kind, handler in previous.items():
            signal.signal(kind, handler)


_UNITS = {"": 1, "k": 10**3, "m": 10**6, "g": 10**9}


def _byte_size(text: str) -> int:
    """``--trace-rotate``: bytes, or a number with k, M or G (powers of 1000)."""
    number, unit = text.rstrip("kKmMgG"), text[len(text.rstrip("kKmMgG")) :].lower()
    try:
        size = int(float(number) * _UNITS[unit])
    except (ValueError, KeyError, OverflowError):
        raise argparse.ArgumentTypeError(f"{text!r} is not a size (e.g. 500k, 64M, 1G)") from None
    if size <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: a size must be positive")
    return size


def _count(text: str) -> int:
    try:
        count = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if count < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be 0 or more")
    return count


def _cmd_run(args: argparse.Namespace) -> int:
    import math

    from rich.console import Console

    from rasm.cli.console import LiveView, print_summary, timeline_note
    from rasm.platform.manifest import load_manifest
    from rasm.platform.platform import Platform

    manifest = load_manifest(args.app)
    if args.duration is not None and not 0 < args.duration < math.inf:  # nan, inf: never ends
        raise UsageError("--duration must be a positive, finite number of seconds")
    if args.trace_rotate is not None and args.trace in (None, "-"):
        raise UsageError("--trace-rotate needs --trace FILE (a file to rotate)")
    scenario = None
    if args.scenario is not None:
        scenario = {**manifest.scenario, **_read_scenario(args.scenario)}
    platform = Platform(
        manifest,
        scenario=scenario,
        clock=args.clock,
        seed=args.seed,
        transport=args.transport,
        trace=args.trace,
        trace_max_bytes=args.trace_rotate,
        trace_keep=args.trace_keep,
        role=args.role,
        low_latency=(args.clock or manifest.clock or "wall") == "wall" and not args.replay,
        replay=args.replay,
    )
    duration = args.duration if args.duration is not None else manifest.duration
    if args.replay is not None and args.duration is None:
        duration = None  # to the recording's end
    console = Console(stderr=args.trace == "-")  # keep stdout for the trace
    dashboard = None
    try:
        with _stop_on_signals(platform):
            platform.build()
            if platform.restored_from is not None:
                console.print(timeline_note(platform), highlight=False, soft_wrap=True)
            if args.dashboard is not None:
                from rasm.report.dashboard import serve

                dashboard = serve(platform, args.dashboard)  # attaches before the run starts
                console.print(f"dashboard: {dashboard.url}")
            if console.is_terminal and args.role != "managed" and duration is not None:
                with LiveView(platform, console, duration=duration):
                    summary = platform.run(duration)
            else:
                summary = platform.run(duration)
    except BaseException:
        if dashboard is not None:
            dashboard.close()
        raise
    print_summary(summary, console)
    if dashboard is not None:
        if sys.stdin.isatty():
            console.print(f"dashboard: {dashboard.url} shows the finished run; Ctrl-C stops it")
            dashboard.hold()
        else:
            dashboard.close()
    return EXIT_OK if summary.ok else EXIT_FAILED


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


# --------------------------------------------------------------------------- parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rasm",
        description="rasm: trustworthy self-adaptive robots (MAPLE-K), statechart-first.",
    )
    parser.add_argument("--version", action="version", version=f"rasm {rasm.__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name: str, func: Callable[[argparse.Namespace], int], help: str):
        p = sub.add_parser(name, help=help, description=help)
        p.set_defaults(func=func)
        return p

    p = command("run", _cmd_run, "run an application's MAPLE-K loop")
    p.add_argument("app", help="application folder (with app.yaml)")
    p.add_argument("--duration", type=float, default=None, help="seconds to run")
    p.add_argument(
        "--transport",
        default=None,
        help="local | mqtt://host:port | zenoh://host:port[?domain=N] | dds://[?domain=N]",
    )
    p.add_argument(
        "--trace",
        default=None,
        help="write the adaptation trace here: JSONL, or MCAP for a name ending in .mcap; "
        "- for standard output",
    )
    p.add_argument(
        "--replay",
        default=None,
        metavar="RECORDING",
        help="drive the loop from a rosbag2 recording (.mcap, .db3 or a bag folder) instead of "
        "the managed system; actions go in the trace, nothing is sent",
    )
    p.add_argument("--trace-rotate", type=_byte_size, default=None, metavar="SIZE",
                   help="rotate the trace file at this size (e.g. 64M): trace.1.jsonl, …")
    p.add_argument("--trace-keep", type=_count, default=4, metavar="N",
                   help="with --trace-rotate, how many older files to keep (default 4)")
    p.add_argument("--clock", choices=["wall", "simulated"], default=None)
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--role", choices=["all", "managing", "managed"], default="all")
    p.add_argument("--scenario", default=None, metavar="JSON|FILE",
                   help="disturbance schedule for the simulator, merged over the manifest's")
    p.add_argument("--dashboard", nargs="?", const=8050, type=int, default=None, metavar="PORT")

    p = command("simulate", _cmd_simulate, "execute one statechart on a simulated clock")
    p.add_argument("chart", help="statechart YAML file")
    p.add_argument("--events", default=None, help="JSONL events file, or - for standard input")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument(
        "--until",
        type=float,
        default=None,
        help="after the last event, advance the clock to this time (timers fire)",
    )

    p = command("check", _cmd_check, "check properties on a trace or a recording offline")
    p.add_argument("props", help="property file (.rv)")
    p.add_argument(
        "trace",
        metavar="RECORDING",
        help="trace file (JSONL, or MCAP from rasm run), or a rosbag2 recording (.mcap, .db3, "
        "a bag folder)",
    )
    p.add_argument("--app", default=None, help="read a recording with this app's probes")
    p.add_argument(
        "--topics", default=None, metavar="MAP.yaml",
        help="read a recording with these probes (a 'probes:' list as in app.yaml)",
    )
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--verdicts", action="store_true", help="print every verdict as JSONL")

    p = command("verify-rules", _cmd_verify_rules, "check legitimacy rules for consistency")
    p.add_argument("rules", help="rules file (YAML), or an app: its rules and fallback actions")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--against", default=None, metavar="PROPS.rv")

    p = command("lint", _cmd_lint, "check statecharts, properties, rules and manifests")
    p.add_argument("paths", nargs="+", metavar="PATH")

    p = command("graph", _cmd_graph, "draw a statechart")
    p.add_argument("chart")
    p.add_argument("--format", choices=["mermaid", "plantuml", "dot"], default="mermaid")

    p = command("monitor", _cmd_monitor, "attach monitors to a live loop")
    p.add_argument("props")
    p.add_argument("--transport", required=True)
    p.add_argument("--topics", default=None, metavar="MAP.yaml")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")

    p = command("report", _cmd_report, "render a trace as a self-contained HTML page")
    p.add_argument("trace")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--props", action="append", default=[], metavar="PROPS.rv",
                   help="property file to check the trace against (repeatable)")
    p.add_argument("--no-platform-props", dest="platform_props", action="store_false",
                   help="leave out the platform's own properties")

    p = command("new", _cmd_new, "create an application skeleton")
    p.add_argument("name")
    p.add_argument("--from", dest="model", default=None, metavar="MODEL.yaml")

    p = command("package", _cmd_package, "build a deployment package")
    p.add_argument("app")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--key-file", default=None, metavar="FILE", help="HMAC key to sign with")
    p.add_argument("--no-deps", action="store_true",
                   help="leave rasm's dependencies out of 01_Binaries")

    p = command("deploy", _cmd_deploy, "verify and install one compute unit of a package")
    p.add_argument("package")
    p.add_argument("--unit", required=True)
    p.add_argument("--to", required=True, dest="target")
    p.add_argument("--key-file", default=None, metavar="FILE", help="HMAC key to verify with")
    p.add_argument("--start", action="store_true", help="start the unit's nodes after validating")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    import signal
    import threading

    parser = build_parser()
    args = parser.parse_args(argv)
    previous = None
    if threading.current_thread() is threading.main_thread():
        # a Ctrl-C raises Interrupted, which user code cannot raise by accident: a
        # KeyboardInterrupt raised inside a chart or a stage fails that step or stage only
        previous = signal.signal(signal.SIGINT, raise_interrupted)
    try:
        return args.func(args)
    except SourceErrors as exc:
        for error in exc.errors:
            print(f"rasm: {printable(str(error))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (RasmError, OSError) as exc:
        print(f"rasm: {printable(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)

