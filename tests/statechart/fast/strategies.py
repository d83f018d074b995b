"""Hypothesis strategies: random sismic statecharts, property statecharts and event scripts.

Charts are built as sismic dicts (the YAML structure) and imported with sismic's own importer, so
they are exactly what a user could write: nested compound and parallel states, final states,
shallow and deep history (with or without memory), guards reading the context, ``after``/``idle``
and ``active``, actions changing the context, ``send()`` (also delayed) and ``notify()``,
eventless and internal transitions, priorities, and contracts on states and transitions.
"""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st
from sismic.io.datadict import import_from_dict
from sismic.model import Statechart

EVENTS = ["a", "b", "c"]
GUARDS = [
    "x > 0",
    "x % 2 == 0",
    "y == 0",
    "x < 3",
    "active('s1')",
    "active('s4') or x > 1",
    "after(1)",
    "idle(1.5)",
    "time >= 2",
    "event is None or event.data.get('v', 0) >= 1",
    "1 / (x + 1) > 0.3",  # raises ZeroDivisionError when x == -1
]
ACTIONS = [
    "x += 1",
    "x -= 1",
    "y = 1 - y",
    "x = 0",
    "send('a')",
    "send('b', v=x)",
    "send('c', delay=1)",
    "notify('ping', v=x)",
    "x += 1\nsend('c')",
]
PRE = ["x >= -2", "x < 4", "y == 0 or x != 2", "x != 1"]
POST = [
    "x <= 4",
    "__old__.x <= x + 1",
    "not sent('b') or x >= 0",
    "received('a') or x < 3",
    "x < 2",
]
INV = ["x < 5", "x > -3", "__old__.y == y or x < 2", "not sent('a') or y == 0", "x < 3"]

META = [
    "state entered",
    "state exited",
    "event consumed",
    "transition processed",
    "event sent",
    "step started",
    "step ended",
    "ping",
]
META_GUARDS = {
    # 1 // (k - 1) raises ZeroDivisionError once an action has set k to 1
    # NAMES is a context name an action may rebind (static guard predicates watch it)
    "state entered": [
        "event.state == 's1'", "event.state in ('s2', 's3')", "1 // (k - 1) >= 0",
        "event.state in NAMES", "not (event.state == 's1' or event.state not in NAMES)",
    ],
    "state exited": [
        "event.state == 's1'", "event.state != 's2'", "after(1)", "'s2' == event.state",
    ],
    "event consumed": [
        "event.event.name == 'a'", "event.event.name != 'b'", "active('p1')",
        "event.event.name in NAMES and k < 3",
    ],
    "transition processed": [
        "event.source == 's1'", "event.target is None", "idle(2)", "event.event is None",
        "event.event is not None and event.event.name in NAMES", "event.event.name == 'b'",
    ],
    "event sent": ["event.event.name == 'c'"],
    "step started": ["time > 1"],
    "step ended": ["k > 1", "time > 4"],
    "ping": ["event.v > 0"],
}


def _contract(draw: Any, with_invariants: bool = True) -> list[dict[str, str]] | None:
    kinds = [("before", PRE), ("after", POST)]
    if with_invariants:
        kinds.append(("always", INV))
    items = []
    for key, pool in kinds:
        if draw(st.integers(0, 5)) == 0:
            items.append({key: draw(st.sampled_from(pool))})
    return items or None


@st.composite
def chart_dicts(
    draw: Any,
    max_states: int = 14,
    contracts: bool = True,
    guards: list[str] = GUARDS,
    actions: list[str] = ACTIONS,
) -> dict[str, Any]:
    """A random statechart, as the dict sismic's YAML importer reads (its guards and actions
    drawn from ``guards`` and ``actions``)."""
    counter = iter(range(1000))
    budget = [max_states]
    sources: list[dict[str, Any]] = []
    names: list[str] = []

    def state(depth: int, in_compound: bool) -> dict[str, Any]:
        name = f"s{next(counter)}"
        names.append(name)
        budget[0] -= 1
        kinds = ["basic", "basic", "basic", "final"]
        if depth < 3 and budget[0] > 2:
            kinds += ["compound", "compound", "parallel"]
        if in_compound:
            kinds += ["history"]
        kind = draw(st.sampled_from(kinds))
        if kind == "history":
            kind = draw(st.sampled_from(["shallow history", "deep history"]))
        node: dict[str, Any] = {"name": name}
        if kind in ("final", "shallow history", "deep history"):
            node["type"] = kind
        if kind in ("compound", "parallel"):
            n = draw(st.integers(1, 3))
            children = [state(depth + 1, kind == "compound") for _ in range(n)]
            if kind == "compound":
                node["states"] = children
                _memories(children)
                if draw(st.integers(0, 6)) > 0:  # sometimes no initial state at all
                    node["initial"] = _initial(children)
            else:
                node["parallel states"] = children
        if kind in ("basic", "compound", "parallel"):
            sources.append(node)
        if kind != "shallow history" and kind != "deep history":
            for key in ("on entry", "on exit"):
                if draw(st.integers(0, 4)) == 0:
                    node[key] = draw(st.sampled_from(actions))
        if contracts:
            contract = _contract(draw)
            if contract:
                node["contract"] = contract
        return node

    def _plain(children: list[dict[str, Any]]) -> list[str]:
        return [c["name"] for c in children if "history" not in c.get("type", "")]

    def _initial(children: list[dict[str, Any]]) -> str:
        # Mostly a plain child; sometimes a history state (resumes, or fails without memory).
        plain = _plain(children)
        if plain and draw(st.integers(0, 5)) > 0:
            return draw(st.sampled_from(plain))
        return draw(st.sampled_from([c["name"] for c in children]))

    def _memories(children: list[dict[str, Any]]) -> None:
        plain = _plain(children)
        for child in children:
            if "history" in child.get("type", "") and plain and draw(st.integers(0, 4)) > 0:
                child["memory"] = draw(st.sampled_from(plain))

    root: dict[str, Any] = {"name": "root", "states": []}
    names.append("root")
    children = [state(1, True) for _ in range(draw(st.integers(1, 4)))]
    root["states"] = children
    _memories(children)
    root["initial"] = _initial(children)
    sources.append(root)

    for node in sources:
        transitions = []
        for _ in range(draw(st.integers(0, 3))):
            t: dict[str, Any] = {}
            target = draw(st.one_of(st.none(), st.sampled_from(names)))
            if target is not None:
                t["target"] = target
            event = draw(st.sampled_from([*EVENTS, *EVENTS, None]))
            if event is not None:
                t["event"] = event
            if draw(st.integers(0, 2)) > 0 or event is None:
                t["guard"] = draw(st.sampled_from(guards))
            if draw(st.booleans()):
                t["action"] = draw(st.sampled_from(actions))
            if draw(st.booleans()):  # often: ties between enabled transitions are errors
                t["priority"] = draw(st.sampled_from(["high", "low", 2, -1, 0]))
            if contracts:
                contract = _contract(draw)
                if contract:
                    t["contract"] = contract
            transitions.append(t)
        if transitions:
            node["transitions"] = transitions
    return {"statechart": {"name": "random", "preamble": "x = 0\ny = 0", "root state": root}}


@st.composite
def charts(draw: Any, max_states: int = 14, contracts: bool = True) -> Statechart:
    """A random statechart (see :func:`chart_dicts`)."""
    return import_from_dict(draw(chart_dicts(max_states=max_states, contracts=contracts)))


@st.composite
def property_charts(draw: Any) -> Statechart:
    """A random property statechart over the meta-events of the charts above."""
    names = ["p0", "p1", "p2", "fail"]
    states: list[dict[str, Any]] = []
    for name in names[:3]:
        transitions = []
        for _ in range(draw(st.integers(0, 3))):
            t: dict[str, Any] = {"target": draw(st.sampled_from(names))}
            kind = draw(st.sampled_from(["meta", "meta", "eventless", "tick"]))
            if kind == "meta":
                event = draw(st.sampled_from(META))
                t["event"] = event
                if draw(st.booleans()):
                    t["guard"] = draw(st.sampled_from(META_GUARDS[event]))
            elif kind == "tick":
                t["event"] = "tick"
            else:
                # Timers only: they disable themselves once fired (the target is entered, the
                # source's idle time reset), while a guard like "k > 2" could fire forever, and
                # sismic executes property statecharts without a step bound.
                t["guard"] = draw(st.sampled_from(["after(2)", "idle(3)"]))
            # notify() is sent without being queued: what a step sent must still be cleared by
            # the step after it, as stock does
            # NAMES rebound to other values, or to a new object each time (watched by identity)
            actions = [
                "k += 1", "k = 0", "notify('seen', k=k)", "NAMES = ('s1', 'a')",
                "NAMES = ('s2', 'b')", "NAMES = NAMES[1:] + NAMES[:1]",
            ]
            if kind == "meta":  # a tick transition sending a tick would never stop either
                actions += ["send('tick')", "send('tick', delay=1)"]
            if draw(st.booleans()):
                t["action"] = draw(st.sampled_from(actions))
            transitions.append(t)
        node: dict[str, Any] = {"name": name}
        if transitions:
            node["transitions"] = transitions
        if draw(st.integers(0, 5)) == 0:
            node["contract"] = [{"always": "k < 4"}]
        states.append(node)
    states.append({"name": "fail", "type": "final"})
    root = {"name": "proot", "initial": "p0", "states": states}
    return import_from_dict(
        {"statechart": {"name": "property", "preamble": "k = 0\nNAMES = ('s2', 'b')",
                        "root state": root}}
    )


# One scripted input: advance the clock by ``dt``, then queue ``event`` with ``data``.
script_items = st.tuples(
    st.sampled_from([0, 0, 0.5, 1, 2.5]),
    st.sampled_from([*EVENTS, "z"]),
    st.sampled_from([{}, {"v": 0}, {"v": 2}]),
)
scripts = st.lists(script_items, max_size=12)
