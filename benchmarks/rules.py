"""verify-rules time on generated rule sets of 10, 100 and 500 rules.

Two families, both seeded and reproducible:

* ``coupled``: 5 modes and a fixed pool of 20 numeric and 3 boolean variables; most rules are
  guarded by a mode, so nearly all rules share variables and form one group for the solver
  (the hard case for the conflict search);
* ``modular``: the same kinds of rules over a variable pool that grows with the rule count (one
  variable per 5 rules), as in a large robot where each subsystem has its own rules.

Each rule bounds one variable or a sum of two under a guard. Ordinary rules are mutually
consistent (upper bounds from 50, lower bounds up to 40) and often imply each other; 4 % are
tight upper bounds (<= 4) that conflict with the lower bounds of their mode, 2 % are
unsatisfiable and 3 % dead. The conflict search cost grows with the number of
*independent* conflicts inside one group of coupled rules (see docs/performance-rules.md).

Prints, per size, the median wall and CPU time of ``verify``, the time of the consistency part
alone (what a run-time swap pays), the time to judge one plan with the compiled engine, the
findings, and the growth exponent between sizes (time ~ n^k, from CPU time; the target is
k <= 2, and under 30 s for 500 rules). The machine is shared: CPU time is the figure to
compare, wall time shows the load.

With ``--plan`` the numeric variables are plan fields (the modes and flags stay context), so
conflicts are judged by SPEC section 7's "some context admits no plan" (an exists-forall question
per candidate set).

    .venv/bin/python benchmarks/rules.py [--sizes 10 100 500] [--repeat 3] [--family coupled]
    .venv/bin/python benchmarks/rules.py --plan
    .venv/bin/python benchmarks/rules.py --worst 2 4 6 8 10
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import time

from rasm.rules import CompiledRules, parse_rules, verify

MODES = ["navigate", "dock", "idle", "inspect", "charge"]


def generate(count: int, family: str, seed: int = 1) -> str:
    """The YAML text of a rules file with ``count`` rules."""
    rng = random.Random(seed * 1000 + count)
    numeric = 20 if family == "coupled" else max(4, count // 5)
    lines = ["variables:", "  mode: {type: enum, values: [" + ", ".join(MODES) + "]}"]
    for i in range(numeric):
        kind = "int" if i % 3 == 0 else "real"
        lines.append(f"  v{i}: {{type: {kind}, min: 0, max: 100}}")
    for i in range(3):
        lines.append(f"  flag{i}: {{type: bool}}")
    lines.append("rules:")
    for index in range(count):
        lines.extend(_rule(rng, index, numeric))
    return "\n".join(lines) + "\n"


def _rule(rng: random.Random, index: int, numeric: int) -> list[str]:
    var = f"v{rng.randrange(numeric)}"
    kind = rng.random()
    mode = rng.choice(MODES)
    if kind < 0.03:  # dead: outside the domain
        when, require = f"{var} > 150", f"{var} <= 10"
    elif kind < 0.05:  # unsatisfiable in its mode
        when, require = f'mode == "{mode}"', f"{var} > 120"
    elif kind < 0.09:  # half of a planted conflict: far below any lower bound of its mode
        when, require = f'mode == "{mode}"', f"{var} <= {rng.randrange(0, 5)}"
    else:
        guard = rng.random()
        if guard < 0.6:
            when = f'mode == "{mode}"'
        elif guard < 0.8:
            when = f'mode == "{mode}" and flag{rng.randrange(3)}'
        elif guard < 0.9:
            when = f"flag{rng.randrange(3)}"
        else:
            when = None
        shape = rng.random()
        if shape < 0.45:  # upper bounds stay above every ordinary lower bound...
            require = f"{var} <= {rng.randrange(50, 101)}"
        elif shape < 0.75:  # ...so that ordinary rules overlap, and many imply each other
            require = f"{var} >= {rng.randrange(5, 41)}"
        else:
            other = f"v{rng.randrange(numeric)}"
            require = f"{var} + {other} <= {rng.randrange(100, 201)}"
    out = [f"  - name: rule_{index}"]
    if when is not None:
        out.append(f"    when: '{when}'")
    out.append(f"    require: '{require}'")
    return out


def worst_case(conflicts: int) -> str:
    """``conflicts`` independent conflicting pairs, all coupled into one group by sum rules.

    Every combination of "which rule of each pair to drop" is a maximal satisfiable subset, so
    the conflict search (MARCO) must visit 2^conflicts of them to prove it found all conflicts.
    """
    lines = ["variables:"]
    lines += [f"  v{i}: {{type: real, min: 0, max: 100}}" for i in range(conflicts + 1)]
    lines.append("rules:")
    for i in range(conflicts):
        lines += [f"  - name: low_{i}", f"    require: 'v{i} <= 10'",
                  f"  - name: high_{i}", f"    require: 'v{i} >= 20'",
                  f"  - name: link_{i}", f"    require: 'v{i} + v{i + 1} <= 150'"]
    return "\n".join(lines) + "\n"


def _plan(rng: random.Random, text: str) -> dict:
    rules = parse_rules(text, source="bench")
    plan: dict = {}
    for name, variable in rules.variables.items():
        if variable.type == "enum":
            plan[name] = rng.choice(variable.values)
        elif variable.type == "bool":
            plan[name] = rng.random() < 0.5
        elif variable.type == "int":
            plan[name] = rng.randrange(0, 101)
        else:
            plan[name] = rng.uniform(0, 100)
    return plan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 500])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--family", choices=["coupled", "modular", "both"], default="both")
    parser.add_argument("--plan", action="store_true",
                        help="the numeric variables are plan fields, modes and flags context")
    parser.add_argument("--worst", type=int, nargs="*", metavar="K",
                        help="instead: K independent conflicts in one coupled group")
    args = parser.parse_args()
    if args.worst:
        print(f"{'conflicts':>9} {'rules':>6} {'cpu s':>7} {'consist s':>9}")
        for count in args.worst:
            rules = parse_rules(worst_case(count), source=f"worst-{count}.yaml")
            cpu = time.process_time()
            report = verify(rules)
            total = time.process_time() - cpu
            cpu = time.process_time()
            verify(rules, redundancy=False)
            print(f"{len(report.conflicts):>9} {len(rules.rules):>6} {total:>7.2f} "
                  f"{time.process_time() - cpu:>9.2f}", flush=True)
        return
    families = ["coupled", "modular"] if args.family == "both" else [args.family]
    for family in families:
        print(f"family {family}" + (", numeric variables as plan fields" if args.plan else ""))
        print(f"{'rules':>6} {'wall s':>7} {'cpu s':>7} {'consist s':>9} {'load s':>7} "
              f"{'plan us':>8} {'unsat':>6} {'confl':>6} {'redund':>6} {'dead':>5} "
              f"{'growth k':>8}")
        previous = None
        for size in args.sizes:
            text = generate(size, family)
            start = time.perf_counter()
            rules = parse_rules(text, source=f"{family}-{size}.yaml")
            load = time.perf_counter() - start
            if args.plan:
                rules = rules.with_plan_fields(n for n in rules.variables if n.startswith("v"))
            times, cpus, consistency = [], [], []
            for _ in range(args.repeat):
                start, cpu = time.perf_counter(), time.process_time()
                report = verify(rules)
                times.append(time.perf_counter() - start)
                cpus.append(time.process_time() - cpu)
                start = time.perf_counter()
                verify(rules, redundancy=False)  # what a run-time swap pays
                consistency.append(time.perf_counter() - start)
            median, cpu_median = statistics.median(times), statistics.median(cpus)
            engine = CompiledRules(rules)
            plans = [_plan(random.Random(i), text) for i in range(20)]
            runs = 200
            start = time.perf_counter()
            for _ in range(runs):
                for plan in plans:
                    engine.evaluate(plan)
            per_plan = (time.perf_counter() - start) / (runs * len(plans)) * 1e6
            growth = ""
            if previous is not None:
                growth = f"{math.log(cpu_median / previous[1]) / math.log(size / previous[0]):.2f}"
            previous = (size, cpu_median)
            print(f"{size:>6} {median:>7.2f} {cpu_median:>7.2f} "
                  f"{statistics.median(consistency):>9.2f} {load:>7.2f} {per_plan:>8.1f} "
                  f"{len(report.unsatisfiable):>6} {len(report.conflicts):>6} "
                  f"{len(report.redundant):>6} {len(report.dead):>5} {growth:>8}", flush=True)


if __name__ == "__main__":
    main()
