"""StageOutcome writes its own __init__ (cheaper than a frozen dataclass's): it must take the same
arguments and make the same object as the __init__ dataclass would generate."""

from __future__ import annotations

import dataclasses
import inspect
import pickle

import pytest

from rasm.platform.stages import StageOutcome

# the class dataclass would make from the same fields, with its generated __init__
Generated = dataclasses.make_dataclass(
    "StageOutcome",
    [
        (f.name, f.type, dataclasses.field(default=f.default))
        for f in dataclasses.fields(StageOutcome)
    ],
    frozen=True,
)

CALLS = [
    ((True,), {}),
    ((True, {"x": 1}), {"duration": 0.25}),
    ((False,), {"error": ValueError("bad"), "traceback": "tb", "duration": 1.5}),
    ((False,), {"timed_out": True, "duration": 2.0}),
    ((False, None, None, "", True, 3.0), {}),
]


def test_the_signature_is_the_generated_one() -> None:
    ours = inspect.signature(StageOutcome.__init__)
    theirs = inspect.signature(Generated.__init__)
    assert [(p.name, p.kind, p.default) for p in ours.parameters.values()] == [
        (p.name, p.kind, p.default) for p in theirs.parameters.values()
    ]


@pytest.mark.parametrize(("args", "kwargs"), CALLS)
def test_the_object_is_the_generated_one(args: tuple, kwargs: dict) -> None:
    ours, theirs = StageOutcome(*args, **kwargs), Generated(*args, **kwargs)
    assert vars(ours) == vars(theirs) and list(vars(ours)) == list(vars(theirs))
    assert repr(ours) == repr(theirs)
    assert ours == StageOutcome(*args, **kwargs)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ours.ok = not ours.ok  # type: ignore[misc]
    assert vars(dataclasses.replace(ours, duration=9.0)) == {**vars(theirs), "duration": 9.0}


def test_hash_pickle_and_missing_arguments_behave_as_generated() -> None:
    ours, theirs = (
        StageOutcome(False, 7, None, "tb", True, 0.5),
        Generated(False, 7, None, "tb", True, 0.5),
    )
    assert hash(ours) == hash(theirs)
    assert pickle.loads(pickle.dumps(ours)) == ours
    with pytest.raises(TypeError):
        StageOutcome()  # type: ignore[call-arg]
