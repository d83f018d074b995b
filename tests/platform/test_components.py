"""What user components return is checked before the loop uses it."""

from __future__ import annotations

import pytest

from rasm.loop import LOOP_KEYS
from rasm.platform.components import StageError, as_signals


def test_a_monitor_result_using_loop_keys_names_the_first_of_them() -> None:
    forged = sorted(LOOP_KEYS)[-2:]
    with pytest.raises(StageError, match=f"monitor returned {forged[0]!r}, a key the loop"):
        as_signals({"temperature": 1.0, forged[1]: 1, forged[0]: 2})
    signals = {"temperature": 1.0}
    assert as_signals(signals) is signals


def test_a_monitor_result_may_not_forge_a_robustness() -> None:
    with pytest.raises(StageError, match="monitor returned 'robustness_band', the Trust"):
        as_signals({"temperature": 1.0, "robustness_band": 9.0})
