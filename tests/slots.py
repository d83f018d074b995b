"""What the slot tests of the hot classes share (tests/statechart_fast, tests/platform)."""

from __future__ import annotations


def shadowed_slots(klass: type) -> list[tuple[str, str, str]]:
    """(slot, class declaring it, class shadowing it) for each slot of ``klass``'s MRO that a
    class earlier in the MRO defines as something else: a read would find that instead."""
    found = []
    mro = klass.__mro__
    for index, owner in enumerate(mro):
        for name in owner.__dict__.get("__slots__", ()):
            for earlier in mro[:index]:
                if name in earlier.__dict__:
                    found.append((name, owner.__name__, earlier.__name__))
    return found


def slot_names(klass: type) -> list[str]:
    """The attribute slots of ``klass``'s MRO (``__dict__`` and ``__weakref__`` left out)."""
    return [
        name
        for base in klass.__mro__
        for name in base.__dict__.get("__slots__", ())
        if name not in ("__dict__", "__weakref__")
    ]
