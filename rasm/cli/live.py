"""``rasm run`` and ``rasm monitor``: the commands that run until their duration or Ctrl-C /
SIGTERM, stopping in order (knowledge persisted, trace closed, summary printed)."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING

from rasm.cli.commands import EXIT_FAILED, EXIT_OK, UsageError
from rasm.errors import read_utf8

if TYPE_CHECKING:
    from rasm.platform.platform import Platform


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


MAX_WALL_SECONDS = "RASM_MAX_WALL_SECONDS"


def _capped(duration: float) -> float:
    """``duration`` cut to ``RASM_MAX_WALL_SECONDS`` when that is set: the guides' tests run the
    wall-clock demos through it instead of waiting a minute for paths other tests cover."""
    import math
    import os

    text = os.environ.get(MAX_WALL_SECONDS, "")
    if not text:
        return duration
    try:
        cap = float(text)
    except ValueError:
        cap = math.nan
    if not 0 < cap < math.inf:
        raise UsageError(f"{MAX_WALL_SECONDS} must be a positive, finite number of seconds, "
                         f"not {text!r}")
    return min(duration, cap)


def _cmd_run(args: argparse.Namespace) -> int:
    import math

    from rich.console import Console

    from rasm.cli.console import LiveView, print_summary, timeline_note
    from rasm.platform.manifest import load_manifest
    from rasm.platform.platform import Platform
    from rasm.platform.run_options import Clock, RunOptions

    manifest = load_manifest(args.app)
    if args.duration is not None and not 0 < args.duration < math.inf:  # nan, inf: never ends
        raise UsageError("--duration must be a positive, finite number of seconds")
    if args.trace_rotate is not None and args.trace in (None, "-"):
        raise UsageError("--trace-rotate needs --trace FILE (a file to rotate)")
    wall = (args.clock or manifest.clock or Clock.WALL) == Clock.WALL and not args.replay
    asked = args.duration if args.duration is not None else manifest.duration
    if args.replay is not None and args.duration is None:
        asked = None  # to the recording's end
    duration = _capped(asked) if wall else asked
    scenario = None
    if args.scenario is not None:
        scenario = {**manifest.scenario, **_read_scenario(args.scenario)}
    platform = Platform(
        manifest,
        RunOptions(
            scenario=scenario,
            clock=args.clock,
            seed=args.seed,
            transport=args.transport,
            trace=args.trace,
            trace_max_bytes=args.trace_rotate,
            trace_keep=args.trace_keep,
            role=args.role,
            low_latency=wall,
            replay=args.replay,
        ),
    )
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
            if console.is_terminal and platform.options.role.manages and duration is not None:
                with LiveView(platform, console, duration=duration):
                    summary = platform.run(duration)
            else:
                summary = platform.run(duration)
    except BaseException:
        if dashboard is not None:
            dashboard.close()
        raise
    print_summary(summary, console)
    if duration != asked:
        from rasm.times import format_seconds

        console.print(f"{MAX_WALL_SECONDS} cut this run to {format_seconds(duration)} s of the "
                      f"{format_seconds(asked)} s asked for", highlight=False)
    if dashboard is not None:
        if sys.stdin.isatty():
            console.print(f"dashboard: {dashboard.url} shows the finished run; Ctrl-C stops it")
            dashboard.hold()
        else:
            dashboard.close()
    return EXIT_OK if summary.ok else EXIT_FAILED




def _cmd_monitor(args: argparse.Namespace) -> int:
    # runs until Ctrl-C / SIGTERM (or --duration S); exit 1 iff some property was violated, in
    # error or never judged.
    # With RASM_ACTION_KEY (hex) set, every verdict is signed and bound to the rasm loops that
    # announce their epoch, so a loop with the key takes it as an external verdict source.
    # With RASM_UPDATE_KEY (hex) set, HMAC-signed {"spec": …} on rasm/update/properties, bound
    # to the epoch this process announces on rasm/presence/monitor-<pid>, replace the properties
    # at run time (the public checker's unsigned `reconfig`, made safe).
    import math
    import os
    import signal
    import threading

    from rasm.attach import Attachment, SignedVerdicts, load_topic_map
    from rasm.comm import open_transport
    from rasm.comm.url import credentials_from_env
    from rasm.platform.distribution import key_from_env
    from rasm.properties import load_specification
    from rasm.times import format_seconds

    duration = getattr(args, "duration", None)
    if duration is not None and not 0 < duration < math.inf:
        raise UsageError(f"--duration must be a positive number of seconds, got {duration}")
    text = read_utf8(args.props)
    signals = list(load_specification(text, source=args.props).signals)
    topics = load_topic_map(args.topics, signals) if args.topics else None
    key = key_from_env("RASM_UPDATE_KEY")
    action_key = key_from_env("RASM_ACTION_KEY")
    if action_key and not args.transport.strip().startswith(("mqtt://", "mqtts://")):
        raise UsageError(
            "RASM_ACTION_KEY signs verdicts over MQTT, where rasm loops announce the epochs to "
            "bind them to: unset it, or monitor over mqtt://"
        )
    transport = open_transport(args.transport, **credentials_from_env(args.transport))
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stop.set())

    def show(verdict) -> None:
        at = format_seconds(verdict.time)
        if verdict.error is not None:
            print(f"error {verdict.property} at t={at}: {verdict.error}", flush=True)
        elif verdict.value is False:
            print(f"violated {verdict.property} at t={at}", flush=True)

    seal = SignedVerdicts(transport, action_key) if action_key else None
    attachment = Attachment(
        text, transport, source=args.props, topics=topics, on_verdict=show,
        verdict_topic=args.verdict_topic, seal=seal,
    )
    transport.connect()
    presence = None
    try:
        if seal is not None:
            seal.start()  # before the first verdict: the loops' retained presence comes at once
        attachment.start()
        if key:
            from rasm.comm import BoundSigner, Presence, UpdateReceiver

            receiver = UpdateReceiver(transport, key, properties=attachment.replace).start()
            # senders bind updates to the epoch announced here (a replayed one is refused);
            # with the action key it is signed, as the loops on the bus require of presence
            presence = Presence(
                transport, f"monitor-{os.getpid()}", role="monitor", info={"epoch": receiver.epoch},
                signer=BoundSigner(action_key) if action_key else None,
            ).start()
        where = args.verdict_topic.format(property="<property>")
        print(
            f"rasm monitor: {len(attachment.monitor.properties)} properties on "
            f"{len(attachment.subscribed_topics)} topic(s) of {args.transport}; verdicts on "
            f"{where}{', signed for the loops that announce their epoch' if seal else ''}; "
            "Ctrl-C stops",
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
        if seal is not None:
            seal.stop()
        if presence is not None:
            presence.stop()
        transport.close()
    sys.stdout.write(summary.format())
    return EXIT_FAILED if summary.failed else EXIT_OK


# --------------------------------------------------------------------------- rules
