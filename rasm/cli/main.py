"""``rasm``'s argument parser and ``main``: each command's arguments, and its function in
:mod:`rasm.cli.commands` or :mod:`rasm.cli.live`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

import rasm
from rasm.cli.commands import (
    EXIT_BAD_INPUT,
    _cmd_check,
    _cmd_deploy,
    _cmd_graph,
    _cmd_lint,
    _cmd_new,
    _cmd_package,
    _cmd_report,
    _cmd_simulate,
    _cmd_verify,
    _cmd_verify_rules,
)
from rasm.cli.live import _byte_size, _cmd_monitor, _cmd_run, _count
from rasm.errors import RasmError, SourceErrors, printable, raise_interrupted
from rasm.extras import missing_extra


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
        "recordings",
        nargs="+",
        metavar="RECORDING",
        help="trace files (JSONL, or MCAP from rasm run), or rosbag2 recordings (.mcap, .db3, "
        "a bag folder): each reported, and a total",
    )
    p.add_argument("--app", default=None, help="read a recording with this app's probes")
    p.add_argument(
        "--topics", default=None, metavar="MAP.yaml",
        help="read a recording with these probes (a 'probes:' list as in app.yaml)",
    )
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--verdicts", action="store_true", help="print every verdict as JSONL")
    p.add_argument("--robustness", action="store_true",
                   help="add each property's robustness (how far from a violation; the "
                   "minimum over the judged records) and, with --verdicts, each verdict's")
    p.add_argument(
        "--allow-damaged", action="store_true",
        help="accept verdicts on what a damaged recording still holds (the damage is reported, "
        "the verdicts that depended on it stay inconclusive, and they pass)",
    )
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="check in N local processes (default: the cores); a large JSONL trace "
                   "is cut into parts checked side by side")
    p.add_argument("--cluster", default=None, metavar="ADDRESS",
                   help="check on an existing Dask distributed cluster, through its scheduler "
                   "(tcp://host:8786); the workers read the recordings at the paths given")
    p.add_argument("--part-size", type=_byte_size, default=None, metavar="SIZE",
                   help="cut JSONL traces into parts of about this size (e.g. 64M; default: "
                   "about two parts per job, none under 8M)")

    p = command("verify-rules", _cmd_verify_rules, "check legitimacy rules for consistency")
    p.add_argument("rules", help="rules file (YAML), or an app: its rules and fallback actions")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--against", default=None, metavar="PROPS.rv")

    p = command("verify", _cmd_verify, "prove a statechart: explore every state it can reach")
    p.add_argument("target", metavar="CHART|APP", help="statechart YAML file")
    p.add_argument("--env", default=None, metavar="ENV.yaml",
                   help="the events that may arrive and how the clock may advance")
    p.add_argument("--properties", default=None, metavar="PROPS.rv",
                   help="past-time properties judged at every macro step")
    p.add_argument("--max-states", type=int, default=100_000, metavar="N",
                   help="stop (inconclusive) after this many states (default 100000)")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--counterexamples", default=None, metavar="DIR",
                   help="write each counterexample there as an events file for rasm simulate")

    p = command("lint", _cmd_lint, "check statecharts, properties, rules and manifests")
    p.add_argument("paths", nargs="+", metavar="PATH")

    p = command("graph", _cmd_graph, "draw a statechart")
    p.add_argument("chart")
    p.add_argument("--format", choices=["mermaid", "plantuml", "dot"], default="mermaid")

    p = command("monitor", _cmd_monitor, "attach monitors to a live loop")
    p.add_argument("props")
    p.add_argument("--transport", required=True)
    p.add_argument("--topics", default=None, metavar="MAP.yaml")
    p.add_argument(
        "--verdict-topic", default="rasm/verdict/{property}", metavar="TEMPLATE",
        help="where each property's verdicts go (default rasm/verdict/{property}; "
        "'{property}' is the public RoboSAPIENS checker's topic named after the property)",
    )
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")

    p = command("report", _cmd_report, "render a trace as a self-contained HTML page")
    p.add_argument("trace")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--props", action="append", default=[], metavar="PROPS.rv",
                   help="property file to check the trace against (repeatable)")
    p.add_argument("--no-platform-props", dest="platform_props", action="store_false",
                   help="leave out the platform's own properties")
    p.add_argument("--app", default=None,
                   help="the app that wrote the trace: its settings of the platform's "
                   "properties (platform_properties:) and its property files")

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
    except ModuleNotFoundError as exc:  # a package of an extra (rasm[ros2]) not installed
        missing = missing_extra(exc, f"rasm {args.command}")
        if missing is None:
            raise
        print(f"rasm: {missing}", file=sys.stderr)
        return EXIT_BAD_INPUT
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
