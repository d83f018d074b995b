"""Node presence over a real mosquitto: start-up, heartbeats, shutdown, a killed and a hung node."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import textwrap

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rasm.comm import LocalTransport, MqttTransport, Presence, PresenceTracker, presence_will
from rasm.comm.presence import presence_topic
from rasm.errors import CommError

NODE = textwrap.dedent(
    """
    import sys
    from rasm.comm import MqttTransport, Presence, presence_will

    url, node, period = sys.argv[1], sys.argv[2], float(sys.argv[3])
    transport = MqttTransport(url, will=presence_will(node, "planner"))
    transport.connect()
    presence = Presence(transport, node, role="planner", period=period).start()
    print("up", flush=True)
    sys.stdin.read()  # until the test closes our stdin
    presence.stop()
    transport.close()
    """
)


class Changes:
    """``on_change`` that queues every change; ``next()`` awaits one (no sleeps)."""

    def __init__(self) -> None:
        self.queue: queue.Queue[tuple[str, str]] = queue.Queue()

    def __call__(self, node: str, state: str) -> None:
        self.queue.put((node, state))

    def next(self, timeout: float = 15.0) -> tuple[str, str]:
        return self.queue.get(timeout=timeout)


@pytest.fixture
def node_process(broker):
    started: list[subprocess.Popen] = []

    def start(name: str, period: float = 0.1) -> subprocess.Popen:
        process = subprocess.Popen(
            [sys.executable, "-c", NODE, broker.url, name, str(period)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        started.append(process)
        assert process.stdout.readline().strip() == "up"
        return process

    yield start
    for process in started:
        if process.poll() is None:
            os.kill(process.pid, signal.SIGCONT)
            process.kill()
        process.wait(timeout=10)


def test_a_killed_node_is_marked_offline_by_its_will(mqtt, node_process):
    changes = Changes()
    tracker = PresenceTracker(mqtt(), timeout=5.0, on_change=changes).start()
    process = node_process("planner-1")
    assert changes.next() == ("planner-1", "online")
    assert tracker.nodes()["planner-1"].role == "planner"
    os.kill(process.pid, signal.SIGKILL)
    assert changes.next() == ("planner-1", "offline")
    assert tracker.nodes()["planner-1"].reason == "lost"
    # the will is retained: a tracker that starts later learns of the crash at once
    late = Changes()
    PresenceTracker(mqtt(), timeout=5.0, on_change=late).start()
    assert late.next() == ("planner-1", "offline")
    tracker.stop()


def test_a_hung_node_becomes_silent_then_online_again_then_shuts_down(mqtt, node_process):
    changes = Changes()
    tracker = PresenceTracker(mqtt(), timeout=1.0, on_change=changes).start()
    process = node_process("executor", period=0.05)
    assert changes.next() == ("executor", "online")
    os.kill(process.pid, signal.SIGSTOP)  # hung: the TCP connection stays up, no heartbeats
    assert changes.next() == ("executor", "silent")
    assert tracker.state("executor") == "silent"
    os.kill(process.pid, signal.SIGCONT)
    assert changes.next() == ("executor", "online")
    process.stdin.close()  # clean shutdown
    assert changes.next() == ("executor", "offline")
    assert tracker.nodes()["executor"].reason == "shutdown"
    assert process.wait(timeout=10) == 0
    tracker.stop()


def test_heartbeats_keep_a_node_online_and_count(mqtt):
    changes = Changes()
    beats: queue.Queue[int] = queue.Queue()
    watcher = mqtt()
    watcher.subscribe("rasm/presence/+", lambda m: beats.put(m.payload.get("seq")), qos=1)
    tracker = PresenceTracker(watcher, timeout=2.0, on_change=changes).start()
    node = MqttTransport(watcher.url, will=presence_will("monitor", "monitor"))
    node.connect()
    with Presence(node, "monitor", role="monitor", period=0.02) as presence:
        assert [beats.get(timeout=10) for _ in range(6)] == [0, 1, 2, 3, 4, 5]
        assert tracker.state("monitor") == "online"
    node.close()
    assert presence.heartbeats >= 5
    assert [changes.next(), changes.next()] == [("monitor", "online"), ("monitor", "offline")]
    assert changes.queue.empty()  # never silent while heartbeats came
    tracker.stop()


def test_a_node_that_announces_but_never_beats_goes_silent(mqtt):
    changes = Changes()
    tracker = PresenceTracker(mqtt(), timeout=0.2, on_change=changes).start()
    node = mqtt()
    presence = Presence(node, "quiet", period=3600).start()
    assert changes.next() == ("quiet", "online")
    assert changes.next() == ("quiet", "silent")
    presence.stop()
    assert changes.next() == ("quiet", "offline")
    tracker.stop()


def test_malformed_presence_messages_are_counted(mqtt):
    changes = Changes()
    tracker = PresenceTracker(mqtt(), timeout=5.0, on_change=changes).start()
    sender = mqtt()
    sender.publish("rasm/presence/x", {"state": "dancing"}, qos=1)
    sender.publish("rasm/presence/x", {"state": "online", "role": 3}, qos=1)
    sender.publish("rasm/presence/x", {"state": "online"}, qos=1)
    assert changes.next() == ("x", "online")  # after the two bad ones, in order
    assert tracker.malformed == 2
    tracker.stop()


def test_names_and_numbers_are_checked():
    assert presence_topic("planner-1") == "rasm/presence/planner-1"
    for bad in ("", "a/b", "+", "#"):
        with pytest.raises(CommError, match="node name"):
            presence_topic(bad)
    with pytest.raises(CommError, match="period"):
        Presence(object(), "n", period=0)  # type: ignore[arg-type]
    with pytest.raises(CommError, match="timeout"):
        PresenceTracker(object(), timeout=-1)  # type: ignore[arg-type]
    will = presence_will("n", "planner")
    assert (will.topic, will.retain, will.qos) == ("rasm/presence/n", True, 1)
    assert will.payload == {"state": "offline", "role": "planner", "reason": "lost"}


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from(["a", "b", "c"]), st.sampled_from(["online", "offline"])),
        max_size=30,
    )
)
def test_on_change_reports_each_change_once_in_order(messages):
    """Whatever the sequence of announcements, ``on_change`` sees exactly the changes."""
    bus = LocalTransport()
    bus.connect()
    seen: list[tuple[str, str]] = []
    tracker = PresenceTracker(bus, timeout=3600, on_change=lambda n, s: seen.append((n, s)))
    tracker.start()
    for node, state in messages:
        bus.publish(presence_topic(node), {"state": state, "role": None})
    expected, last = [], {}
    for node, state in messages:
        if last.get(node) != state:
            expected.append((node, state))
            last[node] = state
    assert seen == expected
    assert {n: s.state for n, s in tracker.nodes().items()} == last
    tracker.stop()
    bus.close()


def test_presence_info_reaches_the_tracker_and_epochs_lists_online_nodes():
    bus = LocalTransport()
    bus.connect()
    tracker = PresenceTracker(bus, timeout=3600).start()
    managed = Presence(bus, "box-managed-1", role="managed", info={"app": "box", "epoch": "e1"})
    other = Presence(bus, "oven-managed-2", role="managed", info={"app": "oven", "epoch": "e2"})
    managing = Presence(bus, "box-managing-3", role="managing", info={"app": "box", "epoch": "e3"})
    for presence in (managed, other, managing):
        presence.start()
    bus.publish(presence_topic("liar"), {"state": "online", "role": "managed", "epoch": 42})
    assert tracker.nodes()["box-managed-1"].payload == {
        "state": "online",
        "role": "managed",
        "period": 1.0,
        "seq": 0,
        "app": "box",
        "epoch": "e1",
    }
    assert tracker.epochs(role="managed", app="box") == {"box-managed-1": "e1"}
    assert tracker.epochs(app="box") == {"box-managed-1": "e1", "box-managing-3": "e3"}
    assert tracker.epochs(role="managed") == {"box-managed-1": "e1", "oven-managed-2": "e2"}
    managed.stop()  # offline: its epoch is no longer one to bind to
    assert tracker.epochs(role="managed", app="box") == {}
    for presence in (other, managing):
        presence.stop()
    tracker.stop()
    bus.close()
    with pytest.raises(CommError, match="own fields"):
        Presence(bus, "n", info={"state": "offline"})


# ---------------------------------------------------------------- signed presence

_KEY = bytes(range(32))


@given(st.lists(st.sampled_from(["bound", "unsigned", "elsewhere", "replay", "other key"]),
                max_size=12))
def test_with_a_gate_only_a_signed_heartbeat_bound_to_the_tracker_counts(kinds):
    from rasm.comm import BoundSigner, SignedGate
    from rasm.comm.message import Message

    gate = SignedGate(_KEY)
    tracker = PresenceTracker(LocalTransport(), gate=gate)
    signer, stranger = BoundSigner(_KEY), BoundSigner(bytes(32))
    topic = presence_topic("robot")
    online = {"state": "online", "role": "managed", "period": 1.0, "app": "a", "epoch": "e1"}
    sent_bound: list[dict] = []
    expected_refused = 0
    for kind in kinds:
        if kind == "bound":
            payload = signer.sign(online, topic=topic, epochs=[gate.epoch])
            sent_bound.append(payload)
        elif kind == "unsigned":
            payload = online
        elif kind == "elsewhere":  # a correct signature for another tracker: an introduction
            payload = signer.sign(online, topic=topic, epochs=["someone-else"])
        elif kind == "replay":
            if not sent_bound:
                continue
            payload = sent_bound[0]
        else:
            payload = stranger.sign(online, topic=topic, epochs=[gate.epoch])
        before = tracker.state("robot")
        tracker._receive(Message(topic, payload))
        if kind == "bound":
            assert tracker.state("robot") == "online"
        else:
            assert tracker.state("robot") == before  # nothing else makes it online
            expected_refused += kind in ("unsigned", "other key", "replay")
    assert tracker.refused == expected_refused
    # who introduced itself with the key is known by its epoch, online or not
    introduced = any(k in ("bound", "elsewhere") for k in kinds)  # a replay follows a bound
    assert tracker.known_epochs(app="a") == (["e1"] if introduced else [])
    assert tracker.epochs(app="a") == ({"robot": "e1"} if sent_bound else {})


@given(st.lists(st.one_of(st.just("offline"), st.integers(0, 3)), max_size=12))
def test_a_node_that_introduces_itself_again_after_going_offline_is_known_again(messages):
    """A node restarted under the same name (a container's pid, a crashed process whose will
    the broker published): whatever came before, after a correctly signed introduction its new
    epoch is the one to bind to, and after an offline message none is."""
    from rasm.comm import BoundSigner, SignedGate
    from rasm.comm.message import Message

    tracker = PresenceTracker(LocalTransport(), gate=SignedGate(_KEY))
    topic = presence_topic("loop")
    expected: list[str] = []
    for message in messages:
        if message == "offline":  # a shutdown or the broker's will: unsigned
            payload = {"state": "offline", "role": "all", "reason": "lost"}
            expected = []
        else:  # an incarnation's introduction, bound to nobody (it does not know the tracker)
            epoch = f"e{message}"
            online = {"state": "online", "role": "all", "period": 1.0, "app": "a", "epoch": epoch}
            payload = BoundSigner(_KEY).sign(online, topic=topic, epochs=[], unbound=True)
            expected = [epoch]
        tracker._receive(Message(topic, payload))
        assert tracker.known_epochs(role="all") == expected
