"""Communication layer speed: MQTT hop latency over loopback mosquitto, local bus throughput.

MQTT cases (each receiver runs in its own process, as separate building blocks would; latency is
``time.perf_counter()`` at the receiver minus the one the sender put in the payload, a clock
shared by all processes of the machine):

- ``hop``: one hop, publisher -> broker -> subscriber, at 10 and 200 msg/s;
- ``relay``: two hops through a middle process whose *callback* republishes each message (a
  MAPLE-K stage handing on its result) — with rasm's MqttTransport, with a plain paho client
  publishing from inside ``on_message`` (how the public platform does it), and with that paho
  client plus TCP_NODELAY on its socket.

Local cases: messages per second through ``LocalTransport.publish`` to one exact subscriber, one
wildcard subscriber among 20 patterns, in strict (JSON round trip) mode, and through a
Endpoints publisher/subscriber queue.

Run: ``.venv/bin/python benchmarks/comm.py [--quick] [--url mqtt://host:port]``. Without ``--url``
a mosquitto is started on a free loopback port (it must be installed). Figures are recorded in
docs/transports.md.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rasm.comm import Endpoints, LocalTransport, Message, MqttTransport  # noqa: E402

WAIT = 30.0


def percentile(sorted_values: list[float], q: float) -> float:
    """Nearest-rank percentile of an already sorted list."""
    if not sorted_values:
        return float("nan")
    rank = max(0, min(len(sorted_values) - 1, round(q / 100 * len(sorted_values) + 0.5) - 1))
    return sorted_values[rank]


# -- processes ---------------------------------------------------------------------------------
def sink_process(url: str, topic: str, count: int, conn) -> None:
    """Receive ``count`` messages on ``topic``; send back their latencies in seconds."""
    import threading

    latencies: list[float] = []
    done = threading.Event()

    def on_message(message: Message) -> None:
        latencies.append(time.perf_counter() - message.payload["t"])
        if len(latencies) >= count:
            done.set()

    with MqttTransport(url) as transport:
        transport.subscribe(topic, on_message)
        conn.send("ready")
        done.wait(WAIT + count / 5)
    conn.send(latencies)


def rasm_relay_process(url: str, conn) -> None:
    """Republish every ``bench/in`` message on ``bench/out`` from the subscription callback."""
    import threading

    with MqttTransport(url) as transport:
        transport.subscribe("bench/in", lambda m: transport.publish("bench/out", m.payload))
        conn.send("ready")
        conn.recv()  # until told to stop
    threading.Event().set()


def paho_relay_process(url: str, conn, nodelay: bool = False) -> None:
    """The same relay written the usual paho way: publish inside ``on_message``.

    With ``nodelay`` the socket gets TCP_NODELAY (as rasm's sockets do), to show how much of the
    difference is Nagle's algorithm holding small packets back.
    """
    import socket

    import paho.mqtt.client as paho
    from paho.mqtt.enums import CallbackAPIVersion

    from rasm.comm.url import parse_mqtt_url

    host, port, _ = parse_mqtt_url(url)
    client = paho.Client(CallbackAPIVersion.VERSION2)
    client.on_message = lambda c, u, msg: c.publish("bench/out", msg.payload)
    if nodelay:
        client.on_socket_open = lambda c, u, sock: sock.setsockopt(
            socket.IPPROTO_TCP, socket.TCP_NODELAY, 1
        )
    client.connect(host, port)
    client.subscribe("bench/in")
    client.loop_start()
    client.publish("bench/ready", b"{}").wait_for_publish(WAIT)  # SUBSCRIBE went out before it
    conn.send("ready")
    conn.recv()
    client.disconnect()
    client.loop_stop()


def paho_nodelay_relay_process(url: str, conn) -> None:
    paho_relay_process(url, conn, nodelay=True)


def burn_cpu(stop) -> None:
    """Background load: spin until told to stop (emulates a robot computer busy with other work)."""
    x = 0
    while not stop.is_set():
        for _ in range(10_000):
            x += 1


def _start(ctx, target: Callable, *args) -> tuple[mp.Process, object]:
    parent, child = ctx.Pipe()
    process = ctx.Process(target=target, args=(*args, child), daemon=True)
    process.start()
    if not parent.poll(WAIT) or parent.recv() != "ready":
        raise RuntimeError(f"{target.__name__} did not become ready")
    return process, parent


def send_paced(url: str, topic: str, rate: float, count: int) -> None:
    """Publish ``count`` messages at ``rate`` per second, each carrying its send time."""
    with MqttTransport(url) as sender:
        start = time.perf_counter() + 0.05
        for i in range(count):
            due = start + i / rate
            delay = due - time.perf_counter()
            if delay > 0:
                time.sleep(delay)  # pacing the load generator, not synchronisation
            sender.publish(topic, {"t": time.perf_counter(), "i": i})


def mqtt_case(url: str, relay: str | None, rate: float, count: int) -> list[float]:
    ctx = mp.get_context("spawn")  # no fork with live paho threads
    relay_proc = relay_conn = None
    if relay == "rasm":
        relay_proc, relay_conn = _start(ctx, rasm_relay_process, url)
    elif relay == "paho":
        relay_proc, relay_conn = _start(ctx, paho_relay_process, url)
    elif relay == "paho+nodelay":
        relay_proc, relay_conn = _start(ctx, paho_nodelay_relay_process, url)
    topic = "bench/out" if relay else "bench/in"
    sink, sink_conn = _start(ctx, sink_process, url, topic, count)
    send_paced(url, "bench/in", rate, count)
    latencies = sink_conn.recv() if sink_conn.poll(WAIT + count / 5) else []
    sink.join(WAIT)
    if relay_proc is not None:
        relay_conn.send("stop")
        relay_proc.join(WAIT)
    if len(latencies) < count:
        print(f"  warning: {count - len(latencies)} of {count} messages lost", file=sys.stderr)
    return sorted(latencies)


# -- local -------------------------------------------------------------------------------------
def local_case(name: str, n: int) -> float:
    """Messages per second for one local scenario."""
    transport = LocalTransport(strict=name == "strict")
    transport.connect()
    received = 0

    def count(message: Message) -> None:
        nonlocal received
        received += 1

    payload = {"velocity": 0.31, "mode": "navigate", "anomaly": False}
    if name == "wildcard":
        for i in range(19):
            transport.subscribe(f"other/{i}/+", count)
        transport.subscribe("robot/+/pose", count)
        topic = "robot/r1/pose"
    else:
        transport.subscribe("robot/pose", count)
        topic = "robot/pose"
    if name == "manager":
        cm = Endpoints(transport)
        subscriber = cm.create_subscriber("robot/pose", maxsize=n)
        publisher = cm.create_publisher("robot/pose")
        begin = time.perf_counter()
        for _ in range(n):
            publisher.publish_message(payload)
            subscriber.get_queue_message()
        elapsed = time.perf_counter() - begin
    else:
        publish = transport.publish
        begin = time.perf_counter()
        for _ in range(n):
            publish(topic, payload)
        elapsed = time.perf_counter() - begin
    assert received == n, (name, received)
    transport.close()
    return n / elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer messages (a smoke run)")
    parser.add_argument("--url", help="an existing broker (default: start mosquitto)")
    parser.add_argument("--no-relay", action="store_true", help="skip the relay cases")
    parser.add_argument(
        "--cpu-load", type=int, default=0, metavar="N",
        help="run N CPU-bound processes meanwhile (a busy machine)",
    )
    args = parser.parse_args(argv)
    ctx = mp.get_context("spawn")
    stop_burning = ctx.Event()
    burners = [ctx.Process(target=burn_cpu, args=(stop_burning,), daemon=True)
               for _ in range(args.cpu_load)]
    for burner in burners:
        burner.start()

    broker = None
    url = args.url
    if url is None:
        from rasm.testing.servers import start_mosquitto

        broker = start_mosquitto(tempfile.mkdtemp(prefix="rasm-bench-"))
        url = broker.url
    seconds = 3 if args.quick else 15
    rows = []
    try:
        cases = [
            (None, "rasm"), ("rasm", "rasm"), ("paho", "plain paho"),
            ("paho+nodelay", "paho + TCP_NODELAY"),
        ]
        for relay, label in cases if not args.no_relay else cases[:1]:
            for rate in (10, 200):
                count = int(rate * seconds)
                lat = mqtt_case(url, relay, rate, count)
                kind = "hop" if relay is None else "relay (2 hops)"
                rows.append((f"mqtt {kind}, {label}", rate, len(lat), lat))
                print(f"  done: {rows[-1][0]} at {rate} msg/s", file=sys.stderr)
    finally:
        stop_burning.set()
        for burner in burners:
            burner.join(WAIT)
        if broker is not None:
            broker.stop()

    load = f", {args.cpu_load} CPU-bound processes running" if args.cpu_load else ""
    print(f"\nMQTT latency over loopback mosquitto ({url}{load}), milliseconds")
    print(f"{'case':<36} {'msg/s':>6} {'n':>6} {'p50':>8} {'p90':>8} {'p99':>8} {'max':>8}")
    for name, rate, n, lat in rows:
        p50, p90, p99 = (percentile(lat, q) * 1e3 for q in (50, 90, 99))
        mx = lat[-1] * 1e3 if lat else float("nan")
        print(f"{name:<36} {rate:>6} {n:>6} {p50:>8.3f} {p90:>8.3f} {p99:>8.3f} {mx:>8.3f}")

    n = 20_000 if args.quick else 200_000
    print("\nLocal transport throughput (one publisher thread, median of 3 runs)")
    print(f"{'case':<36} {'msg/s':>12} {'us/msg':>8}")
    for name in ("exact", "wildcard", "strict", "manager"):
        rate = statistics.median(local_case(name, n) for _ in range(3))
        print(f"{name:<32} {rate:>12,.0f} {1e6 / rate:>8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
