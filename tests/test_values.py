"""rasm.values: whether a value fits its declared type and range, the form it is kept, why not."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.errors import Misfit, RasmError
from rasm.values import SIGNAL_TYPES, TYPES, fit, infer_type, wanted

NOT_SCALARS = st.one_of(st.none(), st.lists(st.integers(), max_size=2), st.just(object()))


def refused(value, kind, **options) -> Misfit:
    with pytest.raises(Misfit) as caught:
        fit(value, kind, **options)
    return caught.value


@given(st.integers())
def test_an_int_fits_a_float_as_a_float_or_kept_exact(n):
    assert type(fit(n, "int")) is int and fit(n, "int") == n
    assert type(fit(n, "float", int_as_float=False)) is int
    try:
        as_float = float(n)
    except OverflowError:
        assert "int too large" in str(refused(n, "float"))
    else:
        assert type(fit(n, "float")) is float and fit(n, "float") == as_float


@pytest.mark.parametrize("kind", ["float", "int"])
@pytest.mark.parametrize("value", [True, False, np.True_])
def test_a_bool_is_not_a_number(kind, value):
    misfit = refused(value, kind)
    assert misfit.reason == f"expected {kind}, got {type(value).__name__}"
    assert str(misfit) == f"expected {kind}, got {type(value).__name__} {value!r}"


@given(st.floats())
def test_a_float_fits_a_float_finite_or_not_unless_finite_is_asked(x):
    kept = fit(x, "float")
    assert type(kept) is float and (kept == x or math.isnan(x))
    if math.isfinite(x):
        assert fit(x, "float", finite=True) == x
    else:
        misfit = refused(x, "float", finite=True)
        assert misfit.reason == "not a finite number"
        assert str(misfit) == f"{x!r} is not a finite number"


@given(st.floats())
def test_a_float_never_fits_an_int_even_when_whole(x):
    assert refused(x, "int").reason == "expected int, got float"
    assert refused(np.float64(x), "int").reason == "expected int, got float64"
    assert type(fit(np.float64(x), "float")) is float


@given(st.floats(), st.floats(allow_nan=False), st.floats(0, 1e300))
def test_a_number_fits_its_range_and_nan_no_range(x, low, width):
    high = low + width
    if low <= x <= high:
        assert fit(x, "float", minimum=low, maximum=high) == x
    else:
        misfit = refused(x, "float", minimum=low, maximum=high)
        assert misfit.reason in (
            f"below the declared minimum {low!r}", f"above the declared maximum {high!r}"
        )
        assert str(misfit) == f"{x!r} is {misfit.reason}"


@given(st.integers(), st.integers(-(10**30), 10**30))
def test_an_int_is_compared_to_its_bounds_exactly(n, bound):
    if n >= bound:
        assert fit(n, "int", minimum=bound) == n
    else:
        assert refused(n, "int", minimum=bound).reason == f"below the declared minimum {bound}"


@given(st.one_of(st.integers(), st.floats(), st.text(), NOT_SCALARS))
def test_bool_takes_true_and_false_only(value):
    assert refused(value, "bool").reason == f"expected bool, got {type(value).__name__}"


def test_numpy_values_are_kept_as_plain_python_values():
    assert type(fit(np.float64(2.5), "float")) is float
    assert type(fit(np.int64(3), "float")) is float
    assert type(fit(np.int64(3), "float", int_as_float=False)) is int
    assert type(fit(np.int64(3), "int")) is int
    assert fit(np.True_, "bool") is True and fit(np.False_, "any") is False
    assert refused(np.float64(2.0), "int").reason == "expected int, got float64"
    assert fit(Fraction(1, 4), "float") == 0.25


def test_a_str_subclass_is_kept_as_a_plain_str():
    class Name(str):
        pass

    kept = fit(Name("dock"), "str")
    assert type(kept) is str and kept == "dock"
    assert refused(b"dock", "str").reason == "expected str, got bytes"


@given(st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(), inner, max_size=3),
    max_leaves=8,
))
def test_a_json_value_is_kept_as_json_gives_it_back(value):
    kept = fit(value, "json")
    assert json.dumps(kept) == json.dumps(json.loads(json.dumps(value)))


def test_a_json_value_is_a_copy_and_what_is_not_json_is_refused_with_a_hint():
    plan = {"steps": ("a", "b")}
    kept = fit(plan, "json")
    assert kept == {"steps": ["a", "b"]}
    kept["steps"].append("c")
    assert plan == {"steps": ("a", "b")}
    misfit = refused({1, 2}, "json")
    assert misfit.reason == "expected a JSON value, got set"
    assert str(misfit).startswith("expected a JSON value, got set {1, 2} (")
    assert "tolist()" in str(misfit)


@given(st.one_of(st.booleans(), st.integers(), st.floats(), st.text()))
def test_any_takes_numbers_strings_and_booleans_as_they_are(value):
    kept = fit(value, "any")
    assert type(kept) is type(value)
    assert kept == value or math.isnan(value)


@given(NOT_SCALARS)
def test_any_refuses_what_is_not_a_scalar(value):
    misfit = refused(value, "any")
    assert misfit.reason == f"expected a number, string or boolean, got {type(value).__name__}"


def test_a_long_value_is_cut_in_the_message():
    misfit = refused("x" * 500, "int")
    assert len(str(misfit)) < 100 and str(misfit).endswith("...")


def test_an_unknown_type_is_a_programming_error():
    with pytest.raises(ValueError, match="unknown type 'double'"):
        fit(1.0, "double")


def test_every_type_has_words_and_misfit_is_a_rasm_error():
    assert [wanted(kind) for kind in SIGNAL_TYPES] == [
        "a number", "an integer", "true or false", "a string", "a number, string or boolean",
    ]
    assert wanted("json") == "a JSON value" and set(TYPES) - set(SIGNAL_TYPES) == {"json"}
    assert issubclass(Misfit, RasmError)


@pytest.mark.parametrize(
    ("value", "kind"),
    [(True, "bool"), (np.True_, "bool"), (3, "int"), (2.5, "float"), ("idle", "str"),
     ([1, 2], "json"), (None, "json")],
)
def test_a_value_infers_its_own_type(value, kind):
    assert infer_type(value) == kind
