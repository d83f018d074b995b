"""Who may speak for an external verdict: the freshness rule for all inputs (any false in the
window keeps the veto, a silent source is stale), and over a real mosquitto an outsider's
`true` clears nothing: not with no real monitor running, not beside a real monitor's `false`
(and with RASM_ACTION_KEY only the key holder's signed verdicts count at all)."""

from __future__ import annotations

import json
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rasm.comm import BoundSigner, PresenceTracker, open_transport
from rasm.platform.external_verdicts import ExternalVerdicts
from rasm.platform.manifest import ExternalVerdict
from rasm.testing.servers import start_mosquitto

from .guarded import write_guarded_app

_MESSAGES = st.lists(
    st.tuples(st.integers(0, 100), st.sampled_from([True, False, 3])), max_size=25
).map(sorted)


@given(
    freshness=st.sampled_from([0.5, 1.0, 3.0]),
    messages=_MESSAGES,
    checks=st.lists(st.integers(0, 120), min_size=1, max_size=20).map(sorted),
)
def test_a_source_vouches_only_when_heard_lately_and_every_recent_verdict_was_true(
    freshness, messages, checks
):
    # times in tenths of a second; messages at a time come before a check at that time
    sources = ExternalVerdicts({"ok": ExternalVerdict("ok", "checker/ok", freshness=freshness)})
    latest = None
    events = sorted([(t, 0, v) for t, v in messages] + [(t, 1, None) for t in checks],
                    key=lambda e: e[:2])
    for tenths, kind, value in events:
        now = tenths / 10
        if kind == 0:
            latest = sources.receive("ok", {"value": value}, now)
            continue
        for verdict in sources.step(now, {}):
            latest = verdict
        heard = [(t / 10, v) for t, v in messages if t <= tenths]
        if not heard:
            assert latest is None and sources.missing("ok") == ("a verdict on checker/ok",)
            continue
        last = heard[-1][0]
        if now >= last + freshness:
            assert latest.value is False and latest.error.startswith("stale"), (now, heard)
        elif any(now < t + freshness for t, v in heard if v is not True):
            assert latest.value is False, (now, heard)  # a false or a non-verdict, in the window
        else:
            assert (latest.value, latest.error) == (True, None), (now, heard)
        # and the platform knows when to look again without a message
        nxt = sources.next_change(now)
        assert nxt is None or nxt > now


def test_a_refused_message_is_counted_and_no_verdict():
    def check(name, payload):
        return None if payload.get("mine") else "unsigned"

    sources = ExternalVerdicts({"ok": ExternalVerdict("ok", "checker/ok")}, check=check)
    assert sources.receive("ok", {"value": True}, 0.0) is None
    assert sources.refused["ok"] == 1 and sources.missing("ok")
    assert sources.receive("ok", {"value": True, "mine": 1}, 0.1).value is True


# ------------------------------------------------------------------ over a real mosquitto


EXTERNAL = """
  external_verdicts:
    checker_ok: {topic: checker/ok, freshness: 0.5}
"""


def _app(tmp_path):
    app = write_guarded_app(tmp_path / "app", period=0.1, veto=("slow",))
    text = (app / "app.yaml").read_text()
    (app / "app.yaml").write_text(text + EXTERNAL)
    return app


class _Publisher:
    """Publishes on a topic every ``period`` seconds from its own thread, until stopped."""

    def __init__(self, transport, topic, payload, period):
        self.transport, self.topic, self.payload, self.period = transport, topic, payload, period
        self.stop = threading.Event()
        self.sent = 0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.wait(self.period):
            self.transport.publish(self.topic, self.payload() if callable(self.payload)
                                   else self.payload)
            self.sent += 1

    def close(self):
        self.stop.set()
        self.thread.join()


def _run_platform(app, url, tmp_path, seconds):
    from rasm import Platform, RunOptions

    platform = Platform(app, RunOptions(
        transport=url,
        clock="wall",
        knowledge="memory",
        state_dir=tmp_path / "state",
        role="all",
    ))
    records: list[dict] = []
    platform.on_record.append(lambda t, r: records.append({"time": t, **r}))
    summary = platform.run(seconds)
    return platform, summary, records


@pytest.mark.slow
def test_an_outsiders_true_clears_no_veto_over_mqtt(tmp_path, monkeypatch):
    broker = start_mosquitto(tmp_path)
    outsider = open_transport(f"mqtt://127.0.0.1:{broker.port}")
    outsider.connect()
    try:
        # no real monitor: the outsider says "true" at 50 Hz for the whole run
        app = _app(tmp_path)
        url = f"mqtt://127.0.0.1:{broker.port}"
        liar = _Publisher(outsider, "checker/ok", {"value": True}, 0.02)
        try:
            # with the key, an unsigned verdict is nobody's: the source is never judged
            monkeypatch.setenv("RASM_ACTION_KEY", "11" * 32)
            platform, summary, records = _run_platform(app, url, tmp_path / "a", 2.0)
            monkeypatch.delenv("RASM_ACTION_KEY")
        finally:
            liar.close()
        assert liar.sent > 20
        assert platform.managing.external_verdicts.refused["checker_ok"] > 20
        assert summary.verdicts["checker_ok"] == "not judged"
        assert not [r for r in records if r.get("executed")]

        # a real monitor says "false" at 10 Hz, the outsider "true" at 50 Hz beside it (no key:
        # the freshness window alone keeps the veto)
        real = _Publisher(outsider, "checker/ok", {"value": False}, 0.1)
        liar = _Publisher(outsider, "checker/ok", {"value": True}, 0.02)
        try:
            platform, summary, records = _run_platform(app, url, tmp_path / "b", 2.0)
        finally:
            real.close()
            liar.close()
        assert summary.verdicts["checker_ok"] == "violated"
        assert not [r for r in records if r.get("executed")], [
            r for r in records if r.get("executed")]
        dropped = [r for r in records if r.get("dropped")]
        assert dropped and all("checker_ok" in r["explanation"] for r in dropped)
    finally:
        outsider.close()
        broker.stop()


@pytest.mark.slow
def test_a_signed_monitor_bound_to_the_loop_speaks_and_a_dead_one_goes_stale(tmp_path, monkeypatch):
    key = "22" * 32
    monkeypatch.setenv("RASM_ACTION_KEY", key)
    broker = start_mosquitto(tmp_path)
    url = f"mqtt://127.0.0.1:{broker.port}"
    monitor = open_transport(url)
    monitor.connect()
    tracker = PresenceTracker(monitor).start()
    signer = BoundSigner(bytes.fromhex(key))
    sent: list[float] = []

    def verdict():
        # what a monitor holding the key sends: bound to the loop's announced epoch
        epochs = sorted(tracker.epochs(role="all", app="guarded").values())
        sent.append(len(epochs))
        payload = {"value": True}
        return signer.sign(payload, topic="checker/ok", epochs=epochs) if epochs else payload

    real = _Publisher(monitor, "checker/ok", verdict, 0.05)
    killed = threading.Timer(2.5, real.close)  # the monitor dies mid-run
    killed.start()
    try:
        platform, summary, records = _run_platform(_app(tmp_path), url, tmp_path / "c", 4.0)
    finally:
        killed.join()
        real.close()
        tracker.stop()
        monitor.close()
        broker.stop()
    executed = [r["time"] for r in records if r.get("executed")]
    assert executed, "the signed verdicts let the loop act"
    # stale 0.5 s after the monitor's last verdict: no action after that
    stale = [r for r in records if "stale: no verdict on checker/ok" in str(r.get("explanation"))]
    assert stale and max(executed) < stale[0]["time"]
    assert summary.verdicts["checker_ok"] == "error"
    assert json.dumps(summary.properties())  # the summary stays JSON-able


def test_a_stale_source_names_its_last_verdicts_time_exactly():
    sources = ExternalVerdicts({"ok": ExternalVerdict("ok", "checker/ok", freshness=0.5)})
    assert sources.receive("ok", {"value": True}, 1700000000.3).value is True
    [stale] = sources.step(1700000000.8, {})
    assert (stale.value, stale.error) == (
        False, "stale: no verdict on checker/ok for 0.5 s (the last at t=1700000000.3)"
    )
