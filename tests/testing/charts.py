"""Small charts with planted bugs (and their fixed versions) for the explorer's tests."""

from __future__ import annotations

# A door with a bolt in a parallel region. Invariant: never open while bolted.
# Planted bug: the bolt can be thrown while the door is open (its guard is missing).
DOOR = """
statechart:
  name: door
  root state:
    name: door
    parallel states:
      - name: leaf
        initial: closed
        states:
          - name: closed
            transitions:
              - target: open
                event: open
                guard: not active('bolted')
          - name: open
            transitions:
              - target: closed
                event: close
      - name: bolt
        initial: unbolted
        states:
          - name: unbolted
            transitions:
              - target: bolted
                event: bolt
                guard: {bolt_guard}
          - name: bolted
            transitions:
              - target: unbolted
                event: unbolt
"""
DOOR_BUGGY = DOOR.format(bolt_guard="1 == 1")
DOOR_FIXED = DOOR.format(bolt_guard="active('closed')")

# A safe that counts failed attempts while locked. Invariant: `open` is never active while
# failed attempts are on record (only `code` unlocks, and it clears them).
# Planted bug: the third attempt on a locked safe opens it (a forgotten debug back door).
SAFE = """
statechart:
  name: safe
  preamble: |
    tries = 0
  root state:
    name: safe
    initial: unlocked
    states:
      - name: unlocked
        transitions:
          - target: locked
            event: lock
          - target: open
            event: pull
      - name: locked
        transitions:
          - target: unlocked
            event: code
            action: |
              tries = 0
          - event: pull
            guard: tries < {limit}
            action: |
              tries += 1
          - target: open
            event: pull
            guard: tries >= {limit}
      - name: open
        transitions:
          - target: unlocked
            event: push
"""
SAFE_BUGGY = SAFE.format(limit=2)
SAFE_FIXED = SAFE.format(limit=10**9)


def safe_invariant(state) -> bool:
    """The safe opens only from unlocked, so never with failed attempts on record."""
    return not (state.active("open") and state.context["tries"] > 0)


# A valve that should close itself `timeout` seconds after opening.
# Planted bug: the timer sends it to `jammed` instead of `shut`.
VALVE = """
statechart:
  name: valve
  preamble: |
    timeout = 4.0
  root state:
    name: valve
    initial: shut
    states:
      - name: shut
        transitions:
          - target: flowing
            event: open
      - name: flowing
        transitions:
          - target: shut
            event: close
          - target: {on_timeout}
            guard: after(timeout)
      - name: jammed
"""
VALVE_BUGGY = VALVE.format(on_timeout="jammed")
VALVE_FIXED = VALVE.format(on_timeout="shut")

# The MAPLE-K stages without the lifecycle: the platform monitors apply (same state names).
# Planted bug: a plan goes straight to executing, skipping legitimating.
MINI_LOOP = """
statechart:
  name: mini_loop
  root state:
    name: loop
    initial: idle
    states:
      - name: idle
        transitions:
          - target: monitoring
            event: tick
      - name: monitoring
        transitions:
          - target: analysing
            event: monitored
      - name: analysing
        transitions:
          - target: planning
            event: anomaly
          - target: idle
            event: no_anomaly
      - name: planning
        transitions:
          - target: {after_planned}
            event: planned
          - target: idle
            event: no_plan
      - name: legitimating
        transitions:
          - target: executing
            event: accepted
          - target: idle
            event: rejected
      - name: executing
        transitions:
          - target: idle
            event: executed
"""
MINI_LOOP_BUGGY = MINI_LOOP.format(after_planned="executing")
MINI_LOOP_FIXED = MINI_LOOP.format(after_planned="legitimating")

# A counter with a contract; planted bug: `add` does not respect the cap.
COUNTER = """
statechart:
  name: counter
  preamble: |
    count = 0
  root state:
    name: counter
    contract:
      - always: count <= 3
    initial: counting
    states:
      - name: counting
        transitions:
          - event: add
            guard: {guard}
            action: |
              count += 1
          - event: reset
            action: |
              count = 0
"""
COUNTER_BUGGY = COUNTER.format(guard="count <= 3")
COUNTER_FIXED = COUNTER.format(guard="count < 3")

# A register that stores the value its `set` event carries. Invariant: never 7.
REGISTER = """
statechart:
  name: register
  preamble: |
    value = 0
  root state:
    name: register
    initial: ready
    states:
      - name: ready
        transitions:
          - event: set
            action: |
              value = event.value
"""
