"""verify-rules time on generated rule sets of 10, 100 and 500 rules (SPEC §8: a benchmark).

Two families, both seeded and reproducible:

* ``coupled``: 5 modes and a fixed pool of 20 numeric and 3 boolean variables; most rules are
  guarded by a mode, so nearly all rules share variables and form one group for the solver
  (the hard case for the conflict search);
* ``modular``: the same kinds of rules over a variable pool that grows with the rule count (one
  variable per 5 rules), as in a large robot where each subsystem has its own rules.

Each rule bounds one variable or a sum of two under a guard. Ordinary rules are mutually
consistent (upper bounds from 50, lower bounds up to 40) and often imply each other; 4 % are
tight upper bounds (<= 4) that conflict with the lower bounds of their mode, 2 % are
unsatisfiable and 3 % dead. The conflict search costs grow with the number of *independent*
conflicts inside one group of coupled rules (``--planted K`` measures that worst case). Prints, per size, the median wall time of ``verify`` and of
judging one plan with the compiled engine, the findings, and the growth exponent between sizes
(time ~ n^k; the target is k <= 2, and under 30 s for 500 rules).

    .venv/bin/python benchmarks/rules.py [--sizes 10 100 500] [--repeat 3] [--family coupled]
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
    args = parser.parse_args()
    families = ["coupled", "modular"] if args.family == "both" else [args.family]
    for family in families:
        print(f"family {family}")
        print(f"{'rules':>6} {'verify s':>9} {'load s':>7} {'plan us':>8} {'unsat':>6} "
              f"{'confl':>6} {'redund':>6} {'dead':>5} {'growth k':>8}")
        previous = None
        for size in args.sizes:
            text = generate(size, family)
            start = time.perf_counter()
            rules = parse_rules(text, source=f"{family}-{size}.yaml")
            load = time.perf_counter() - start
            times = []
            for _ in range(args.repeat):
                start = time.perf_counter()
                report = verify(rules)
                times.append(time.perf_counter() - start)
            median = statistics.median(times)
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
                growth = f"{math.log(median / previous[1]) / math.log(size / previous[0]):.2f}"
            previous = (size, median)
            print(f"{size:>6} {median:>9.2f} {load:>7.2f} {per_plan:>8.1f} "
                  f"{len(report.unsatisfiable):>6} {len(report.conflicts):>6} "
                  f"{len(report.redundant):>6} {len(report.dead):>5} {growth:>8}", flush=True)


if __name__ == "__main__":
    main()
