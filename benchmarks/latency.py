"""Distribution latency: ``rasm monitor`` over loopback mosquitto, and Redis knowledge sharing.

Cases, each at 10 and 200 records/s (percentiles p50/p90/p99 in milliseconds):

- ``hop``: publisher -> broker -> subscriber (the bare MQTT hop, for reference);
- ``monitor``: publisher -> broker -> ``rasm monitor`` (a separate process: the command line
  itself, started as a user would) -> monitor step -> verdict published -> broker -> subscriber.
  That is one hop plus the verdict's publication: what an external Trustworthiness Checker adds
  between a record and its verdict;
- ``knowledge`` (if redis-server is installed): ``register_knowledge`` on one
  :class:`RedisKnowledgeBase` -> Redis -> the subscriber callback of another one (a second
  connection, as a second process would have).

Latency is measured with ``time.perf_counter()`` (CLOCK_MONOTONIC, shared by every process of
the machine): the sender puts it in the record's ``time``, the verdict carries that time back.
The detect-to-act path of a whole loop (anomaly -> executed over the broker) is measured by
``benchmarks/latency_loop.py``.

Run: ``.venv/bin/python benchmarks/latency.py [--quick] [--url mqtt://host:port]``. Without
``--url`` a mosquitto is started on a free loopback port. Figures are in docs/distribution.md.
"""

from __future__ import annotations

import argparse
import queue
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rasm.comm import Message, MqttTransport  # noqa: E402

PROPS = "input velocity: float\nproperty velocity_limit:\n    always (velocity <= 0.5)\n"


def percentile(sorted_values: list[float], q: float) -> float:
    """Nearest-rank percentile of an already sorted list."""
    if not sorted_values:
        return float("nan")
    rank = max(0, min(len(sorted_values) - 1, round(q / 100 * len(sorted_values) + 0.5) - 1))
    return sorted_values[rank]


def summary(name: str, rate: int, latencies: list[float], expected: int) -> str:
    ms = sorted(x * 1000 for x in latencies)
    lost = expected - len(ms)
    return (
        f"{name:<10} {rate:>4}/s  n={len(ms):<5} p50 {percentile(ms, 50):7.3f} ms  "
        f"p90 {percentile(ms, 90):7.3f} ms  p99 {percentile(ms, 99):7.3f} ms  "
        f"max {ms[-1] if ms else float('nan'):7.3f} ms  lost {lost}"
    )


def paced(rate: int, count: int):
    """Yield ``count`` times at ``rate`` per second (sleeping until each slot)."""
    start = time.perf_counter()
    for i in range(count):
        slot = start + i / rate
        delay = slot - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        yield i


def mqtt_case(url: str, rate: int, count: int, props: Path) -> tuple[list[float], list[float]]:
    """Latencies of the bare hop and of hop + rasm monitor + verdict, in seconds."""
    monitor = subprocess.Popen(
        [sys.executable, "-m", "rasm.cli", "monitor", str(props), "--transport", url],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        ready = monitor.stderr.readline()
        if not ready.startswith("rasm monitor:"):
            raise RuntimeError(f"rasm monitor did not start: {ready}{monitor.stderr.read()}")
        hops: queue.Queue[float] = queue.Queue()
        verdicts: queue.Queue[float] = queue.Queue()
        receiver = MqttTransport(url)
        sender = MqttTransport(url)
        receiver.connect()
        sender.connect()

        def on_hop(message: Message) -> None:
            hops.put(time.perf_counter() - message.payload["time"])

        def on_verdict(message: Message) -> None:
            verdicts.put(time.perf_counter() - message.payload["time"])

        receiver.subscribe("velocity", on_hop)
        receiver.subscribe("rasm/verdict/velocity_limit", on_verdict)
        for i in paced(rate, count):
            sender.publish("velocity", {"value": 0.1 + (i % 5) * 0.1, "time": time.perf_counter()})
        hop = [hops.get(timeout=30) for _ in range(count)]
        verdict = []
        for _ in range(count):
            try:
                verdict.append(verdicts.get(timeout=30))
            except queue.Empty:
                break
        sender.close()
        receiver.close()
        return hop, verdict
    finally:
        monitor.terminate()
        monitor.wait(timeout=30)


def knowledge_case(redis_url: str, rate: int, count: int) -> list[float]:
    from rasm.knowledge import RedisKnowledgeBase

    writer = RedisKnowledgeBase(redis_url, namespace=f"bench{rate}")
    reader = RedisKnowledgeBase(redis_url, namespace=f"bench{rate}")
    writer.clear()
    got: queue.Queue[float] = queue.Queue()
    reader.subscribe(lambda key, sample: got.put(time.perf_counter() - sample.value))
    for _ in paced(rate, count):
        now = time.perf_counter()
        writer.register_knowledge("stamp", now, now)
    latencies = [got.get(timeout=30) for _ in range(count)]
    writer.clear()
    writer.close()
    reader.close()
    return latencies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer records (a smoke run)")
    parser.add_argument("--url", help="an existing broker (default: start mosquitto)")
    parser.add_argument("--redis", help="an existing redis:// server (default: start one)")
    args = parser.parse_args()
    seconds = 2 if args.quick else 10
    servers = []
    with tempfile.TemporaryDirectory() as tmp:
        try:
            url = args.url
            if url is None:
                from rasm.testing.servers import start_mosquitto

                servers.append(start_mosquitto(tmp))
                url = servers[-1].url
            redis_url = args.redis
            if redis_url is None:
                from rasm.testing.servers import start_redis

                try:
                    servers.append(start_redis(tmp))
                    redis_url = servers[-1].url
                except FileNotFoundError:
                    redis_url = None
            props = Path(tmp) / "latency.rv"
            props.write_text(PROPS)
            print(f"python {sys.version.split()[0]}, broker {url}, {seconds} s per case")
            for rate in (10, 200):
                count = rate * seconds
                hop, verdict = mqtt_case(url, rate, count, props)
                print(summary("hop", rate, hop, count))
                print(summary("monitor", rate, verdict, count))
                if redis_url is not None:
                    print(summary("knowledge", rate, knowledge_case(redis_url, rate, count), count))
        finally:
            for server in servers:
                server.stop()


if __name__ == "__main__":
    main()
