"""Statechart execution speed: stock sismic against rasm's FastInterpreter and the platform's.

Runs the interpreters on the same charts and the same event sequences, in one process, interleaved
(median of several runs), and prints events per CPU second for each case with the ratios to stock
sismic. The last lines are ``platform_min_ratio=X.XX`` (``rasm.statechart.Interpreter``) and
``min_ratio=X.XX`` (``rasm.statechart.fast.FastInterpreter``).

Cases (see docs/performance-statecharts.md for the figures):

- ``flat``: a flat 3-state cycle, one ``next`` event per step;
- ``parallel-all``: six parallel 5-state lifecycles, every region firing on each event;
- ``parallel-one``: the same chart, one region firing per event;
- ``parallel-all+property`` / ``parallel-one+property``: the same with a property statechart bound;
- ``orchestrator``: the platform's MAPLE-K orchestrator
  (``statecharts/adaptation_orchestrator.yaml``) through full loop iterations, if that chart exists;
- ``orchestrator+monitors``: the same with the property statecharts of ``monitors/`` bound,
  as the platform runs it.

Run: ``.venv/bin/python benchmarks/statecharts.py [--quick]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from sismic.interpreter import Interpreter
from sismic.io import import_from_yaml
from sismic.model import Statechart

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rasm.statechart import Interpreter as PlatformInterpreter  # noqa: E402
from rasm.statechart.fast import FastInterpreter  # noqa: E402

FLAT = """
statechart:
  name: flat
  root state:
    name: root
    initial: a
    states:
    - name: a
      transitions:
      - {target: b, event: next}
    - name: b
      transitions:
      - {target: c, event: next}
    - name: c
      transitions:
      - {target: a, event: next}
"""

REGIONS = 6
LIFECYCLE = ["created", "configured", "running", "paused", "stopped"]


def lifecycles_yaml() -> str:
    """Six parallel 5-state lifecycles; region i answers ``step`` (all) and ``step_i`` (one)."""
    lines = [
        "statechart:",
        "  name: lifecycles",
        "  root state:",
        "    name: root",
        "    initial: running_all",
        "    states:",
        "    - name: running_all",
        "      parallel states:",
    ]
    for i in range(REGIONS):
        lines += [f"      - name: r{i}", f"        initial: r{i}_{LIFECYCLE[0]}", "        states:"]
        for k, name in enumerate(LIFECYCLE):
            nxt = LIFECYCLE[(k + 1) % len(LIFECYCLE)]
            lines += [
                f"        - name: r{i}_{name}",
                "          transitions:",
                f"          - {{target: r{i}_{nxt}, event: step}}",
                f"          - {{target: r{i}_{nxt}, event: step_{i}}}",
            ]
    return "\n".join(lines) + "\n"


# A typical timeliness property: once region 0 is running it must pause within 10 s.
PROPERTY = """
statechart:
  name: r0 pauses within 10 s of running
  root state:
    name: root
    initial: idle
    states:
    - name: idle
      transitions:
      - target: waiting
        event: state entered
        guard: event.state == 'r0_running'
    - name: waiting
      transitions:
      - target: idle
        event: state entered
        guard: event.state == 'r0_paused'
      - target: failure
        guard: after(10)
    - name: failure
      type: final
"""


def run_events(make: Callable[[], Interpreter], events: Sequence[str], dt: float) -> float:
    """Queue and execute ``events`` one at a time, advancing the clock; return events per CPU
    second (the process's own time: other processes on the machine count less)."""
    interp = make()
    interp.execute()
    start = time.process_time()
    for name in events:
        interp.clock.time += dt
        interp.queue(name)
        interp.execute()
    return len(events) / (time.process_time() - start)


def case(
    chart: Statechart,
    events: Sequence[str],
    prop: Statechart | Sequence[Statechart] | None,
    dt: float = 0.1,
):
    """Return (stock, rasm, platform-or-None factories, events, dt) for a chart and properties."""
    props = [] if prop is None else [prop] if isinstance(prop, Statechart) else list(prop)

    def factory(klass, own_property_class=True):
        def make():
            interp = klass(chart)
            for bound in props:
                if own_property_class:
                    interp.bind_property_statechart(bound, interpreter_klass=klass)
                else:  # the platform binds properties with its own default class
                    interp.bind_property_statechart(bound)
            return interp

        return make

    platform = factory(PlatformInterpreter, own_property_class=False)
    return factory(Interpreter), factory(FastInterpreter), platform, events, dt


def orchestrator_case(n_iterations: int, monitors: bool = False):
    """The MAPLE-K orchestrator through full loop iterations (with the property statecharts of
    ``monitors/`` bound, as the platform runs it, if ``monitors``), or None if absent."""
    path = ROOT / "statecharts" / "adaptation_orchestrator.yaml"
    if not path.exists():
        return None
    chart = import_from_yaml(filepath=str(path))
    props = (
        [import_from_yaml(filepath=str(p)) for p in sorted((ROOT / "monitors").glob("*.yaml"))]
        if monitors
        else None
    )
    setup = ["configure", "configuration_done", "initialization_done"]
    loop = ["tick", "monitored", "anomaly", "planned", "accepted", "executed"]
    events = setup + loop * n_iterations
    return case(chart, events, props)


def measure(factories, events, dt, repeats: int) -> list[float]:
    """Median events/s of each factory over ``repeats`` interleaved runs."""
    runs: list[list[float]] = [[] for _ in factories]
    for _ in range(repeats):
        for found, make in zip(runs, factories, strict=True):
            found.append(run_events(make, events, dt))
    return [statistics.median(found) for found in runs]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer events and repeats")
    parser.add_argument("--repeats", type=int, default=None)
    args = parser.parse_args(argv)
    n = 600 if args.quick else 3000
    repeats = args.repeats or (3 if args.quick else 5)

    flat = import_from_yaml(FLAT)
    lifecycles = import_from_yaml(lifecycles_yaml())
    prop = import_from_yaml(PROPERTY)
    one = [f"step_{i % REGIONS}" for i in range(n)]
    cases = {
        "flat": case(flat, ["next"] * n, None),
        "parallel-all": case(lifecycles, ["step"] * (n // 3), None),
        "parallel-one": case(lifecycles, one, None),
        "parallel-all+property": case(lifecycles, ["step"] * (n // 6), prop),
        "parallel-one+property": case(lifecycles, one[: n // 3], prop),
    }
    orch = orchestrator_case(n // 6)
    if orch is None:
        print("note: statecharts/adaptation_orchestrator.yaml absent, orchestrator case skipped")
    else:
        cases["orchestrator"] = orch
        cases["orchestrator+monitors"] = orchestrator_case(n // 24, monitors=True)

    # "rasm" is the fast path (FastInterpreter); "platform" adds the atomic-step layer and the
    # deadline-recording evaluator (rasm.statechart.Interpreter), what the platform runs.
    ratios, platform_ratios = [], []
    header = f"{'case':<24}{'stock ev/s':>12}{'rasm ev/s':>12}{'ratio':>8}"
    print(header + f"{'platform ev/s':>15}{'ratio':>8}")
    for name, (stock, rasm, platform, events, dt) in cases.items():
        s, r, p = measure([stock, rasm, platform], events, dt, repeats)
        ratios.append(r / s)
        platform_ratios.append(p / s)
        print(f"{name:<24}{s:>12,.0f}{r:>12,.0f}{r / s:>8.2f}{p:>15,.0f}{p / s:>8.2f}")
    print(f"platform_min_ratio={min(platform_ratios):.2f}")
    print(f"min_ratio={min(ratios):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
