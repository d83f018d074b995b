"""The platform's evaluator runs actions exactly as sismic's, exposing only the names they use."""

from __future__ import annotations

import pytest
from sismic.code import PythonEvaluator
from sismic.exceptions import CodeEvaluationError
from sismic.interpreter import Interpreter as StockInterpreter
from sismic.io.datadict import import_from_dict

from rasm.statechart.interpreter import FastGuardEvaluator

ACTIONS = [
    "x = 1",
    "send('ping', v=x)",
    "notify('seen', k=2)",
    "x = active('s') and time",
    "setdefault('y', 3)",
    "x = sorted(k for k in globals() if not k.startswith('__'))",
    "f = lambda: send('later')\nf()",
    "x = 1 // 0",
    "x = event.name if event else None",
    "x = undefined_name",
]


def chart(action: str):
    states = [
        {"name": "s", "on entry": action, "transitions": [
            {"target": "t", "event": "go", "action": action}]},
        {"name": "t", "on entry": action},
    ]
    return import_from_dict({"statechart": {
        "name": "actions", "preamble": "x = 0",
        "root state": {"name": "root", "initial": "s", "states": states},
    }})


def outcome(evaluator, action: str):
    interp = StockInterpreter(chart(action), evaluator_klass=evaluator)
    seen = []
    interp.attach(lambda meta: seen.append((meta.name, sorted(meta.data))))
    results = []
    for event in (None, "go"):
        if event:
            interp.queue(event)
        try:
            steps = interp.execute()
            results.append([[repr(e) for m in s.steps for e in m.sent_events] for s in steps])
        except CodeEvaluationError as exc:
            results.append(("error", str(exc)))
    # functions an action defined are new objects in each run: compared by what they do above
    context = sorted((k, "<function>" if callable(v) else v) for k, v in interp.context.items())
    return results, seen, context, interp.configuration


@pytest.mark.parametrize("action", ACTIONS)
def test_actions_do_what_sismic_does(action):
    assert outcome(FastGuardEvaluator, action) == outcome(PythonEvaluator, action)
