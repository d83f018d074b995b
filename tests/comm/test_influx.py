"""MAPLE-K timing as InfluxDB line protocol, written to a real influxd and queried back."""

from __future__ import annotations

import http.server
import itertools
import threading

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rasm.comm import InfluxWriter
from rasm.comm.influx import escape_key, field_value, query, record_to_points, verdict_to_point
from rasm.errors import CommError
from rasm.properties import compile_properties

_databases = itertools.count()


def _db() -> str:
    return f"test{next(_databases)}"


def _rows(url: str, db: str, q: str) -> list[dict]:
    """Query influxd and return one dict per row."""
    out = []
    for series in query(url, db, q):
        for values in series["values"]:
            out.append(dict(zip(series["columns"], values, strict=True)))
    return out


# ----------------------------------------------------------------------- line protocol


def test_record_to_points_maps_stages_events_and_signals():
    assert record_to_points(12.5, {"stage": "plan", "duration": 0.0031}) == [
        "maple_stage,stage=plan start=12.5,duration=0.0031 12500000"
    ]
    lines = record_to_points(
        13.0,
        {
            "rejected": True,
            "plan": "p 7",
            "broken_rules": ["slow_docking", "b"],
            "explanation": 'velocity "0.3" > 0.1',
            "velocity": 3,
            "mode": "dock",
            "ok": False,
        },
    )
    assert lines == [
        'adaptation,event=rejected,plan=p\\ 7 value=true,broken_rules="slow_docking,b",'
        'explanation="velocity \\"0.3\\" > 0.1" 13000000',
        'knowledge velocity=3.0,mode="dock",ok=false 13000000',
    ]
    both = record_to_points(1.0, {"anomaly": True, "planned": True, "legitimate": False})
    assert [line.split(" ")[0] for line in both] == [
        "adaptation,event=anomaly",
        "adaptation,event=planned",
    ]
    assert record_to_points(1.0, {"x": float("nan"), "y": None, "z": [1, 2]}) == []
    assert record_to_points(2.0, {"x": 1}, precision="s") == ["knowledge x=1.0 2"]
    with pytest.raises(CommError, match="precision"):
        record_to_points(1.0, {}, precision="h")


def test_verdict_points():
    assert verdict_to_point("velocity_limit", 2.5, False, index=4) == (
        "verdict,property=velocity_limit value=false,index=4.0 2500000"
    )
    assert verdict_to_point("p", 1.0, None) is None


def test_names_are_escaped_and_cleaned():
    assert escape_key("a b,c=d") == "a\\ b\\,c\\=d"
    assert escape_key("line\nbreak\\x") == "line\\ break/x"
    assert field_value('say "hi"\\') == '"say \\"hi\\"\\\\"'
    assert field_value(float("inf")) is None and field_value(True) == "true"


# ----------------------------------------------------------------------- against influxd


def test_stage_verdict_and_adaptation_points_are_queried_back(influx):
    db = _db()
    monitor = compile_properties("property fast: always (duration <= 0.01)")
    with InfluxWriter(influx.url, db) as writer:
        records = [
            (1.0, {"stage": "monitor", "duration": 0.002}),
            (1.002, {"stage": "analyse", "duration": 0.004}),
            (1.006, {"anomaly": True, "plan": "p1", "temperature": 31.5}),
            (1.006, {"stage": "plan", "duration": 0.02}),
            (1.03, {"rejected": True, "plan": "p1", "broken_rules": ["slow"]}),
            (1.05, {"executed": True, "plan": "p2"}),
        ]
        for time, record in records:
            writer.write_record(time, record)
            if "duration" in record:
                for verdict in monitor.step(time, {"duration": record["duration"]}):
                    writer.write_verdict(verdict)
        assert writer.flush()
        # 3 stages, 3 verdicts, 3 events, 1 knowledge point (temperature)
        assert writer.stats.as_dict() == {
            "written": 10,
            "dropped": 0,
            "failed": 0,
            "batches": writer.stats.batches,
        }
    stages = _rows(influx.url, db, 'SELECT stage, start, "duration" FROM maple_stage')
    assert [(r["time"], r["stage"], r["start"], r["duration"]) for r in stages] == [
        (1_000_000, "monitor", 1.0, 0.002),
        (1_002_000, "analyse", 1.002, 0.004),
        (1_006_000, "plan", 1.006, 0.02),
    ]
    verdicts = _rows(influx.url, db, "SELECT property, value, index FROM verdict")
    assert [(r["property"], r["value"], r["index"]) for r in verdicts] == [
        ("fast", True, 0.0),
        ("fast", True, 1.0),
        ("fast", False, 2.0),
    ]
    events = _rows(influx.url, db, "SELECT event, plan, value, broken_rules FROM adaptation")
    assert [(r["event"], r["plan"], r["broken_rules"]) for r in events] == [
        ("anomaly", "p1", None),
        ("rejected", "p1", "slow"),
        ("executed", "p2", None),
    ]
    mean = _rows(influx.url, db, 'SELECT mean("duration") FROM maple_stage GROUP BY stage')
    assert sorted(round(r["mean"], 6) for r in mean) == [0.002, 0.004, 0.02]


names = st.text(
    alphabet=st.characters(blacklist_categories=("Cs", "Cc")), min_size=1, max_size=12
).filter(lambda s: s.strip() and "\\" not in s)
strings = st.text(
    alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\r\0"), max_size=30
)


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    stage=names,
    plan=names,
    text=strings,
    number=st.floats(allow_nan=False, allow_infinity=False, width=64),
)
def test_any_text_and_number_survives_the_trip(influx, stage, plan, text, number):
    db = _db()
    lines = record_to_points(5.0, {"stage": stage, "duration": number})
    lines += record_to_points(6.0, {"rejected": True, "plan": plan, "explanation": text})
    writer = InfluxWriter(influx.url, db)
    writer.write(lines)
    writer.close()
    assert writer.stats.written == 2, writer.stats
    stages = _rows(influx.url, db, 'SELECT stage, "duration" FROM maple_stage')
    # InfluxDB's JSON prints a float without a fraction as an integer: compare as floats
    assert [(r["stage"], float(r["duration"])) for r in stages] == [(stage, number)]
    events = _rows(influx.url, db, "SELECT plan, value, explanation FROM adaptation")
    assert [(r["plan"], r["explanation"]) for r in events] == [(plan, text or None)]


# ----------------------------------------------------------------------- the writer's behaviour


def test_a_full_queue_drops_and_counts(influx):
    writer = InfluxWriter(influx.url, _db(), max_queue=3, batch_size=100)
    assert writer.write([f"m x={i} {i}" for i in range(8)]) == 3
    assert writer.stats.dropped == 5
    writer.close()
    assert writer.stats.written == 3


def test_an_unreachable_server_fails_batches_without_raising(tmp_path, caplog):
    from rasm.testing.servers import free_port

    url = f"http://127.0.0.1:{free_port()}"
    writer = InfluxWriter(url, "x", timeout=1.0)
    writer.write_record(1.0, {"stage": "monitor", "duration": 0.1})
    assert writer.flush()
    assert (writer.stats.failed, writer.stats.written) == (1, 0)
    writer.write_record(2.0, {"stage": "plan", "duration": 0.1})  # still accepted
    writer.close()
    assert writer.stats.failed == 2
    # logged once, naming the server and the operation; the second batch only counted
    logged = [r.getMessage() for r in caplog.records if r.name == "rasm.comm.influx"]
    assert len(logged) == 1 and logged[0].startswith(f"timing server {url}: writing failed")
    assert (writer.failure.failures, writer.failure.lost) == (2, 2)


def test_refused_points_are_counted_as_failed(influx):
    writer = InfluxWriter(influx.url, _db())
    writer.write(["this is not line protocol"])
    writer.close()
    assert (writer.stats.failed, writer.stats.written) == (1, 0)


class _HeldServer(http.server.ThreadingHTTPServer):
    """An HTTP server whose /write answers only once ``release`` is set; records the bodies."""

    def __init__(self) -> None:
        self.release = threading.Event()
        self.arrived = threading.Event()
        self.bodies: list[str] = []
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"])).decode()
                outer.bodies.append(body)
                outer.arrived.set()
                outer.release.wait(30)
                self.send_response(204)
                self.end_headers()

            def log_message(self, *args) -> None:
                pass

        super().__init__(("127.0.0.1", 0), Handler)


def test_writing_never_waits_for_the_server():
    server = _HeldServer()
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        writer = InfluxWriter(f"http://127.0.0.1:{server.server_address[1]}", "db", batch_size=2)
        writer.write(["m x=1 1", "m x=2 2"])  # a full batch: sent at once
        assert server.arrived.wait(10)
        # the server holds that request; the loop keeps writing all the same
        for i in range(3, 103):
            assert writer.write([f"m x={i} {i}"]) == 1
        assert writer.flush(timeout=0.05) is False  # not written yet: the server holds it
        server.release.set()
        assert writer.flush(timeout=10)
        writer.close()
        assert writer.stats.written == 102 and writer.stats.dropped == 0
        assert server.bodies[0] == "m x=1 1\nm x=2 2\n"
    finally:
        server.release.set()
        server.shutdown()
        server.server_close()


def test_to_file_writes_the_same_lines(tmp_path):
    path = tmp_path / "timing" / "maple.lp"
    records = [(1.0, {"stage": "monitor", "duration": 0.5}), (2.0, {"executed": True, "plan": "a"})]
    with InfluxWriter.to_file(path) as writer:
        for time, record in records:
            writer(time, record)  # a trace observer
    expected = [line for time, record in records for line in record_to_points(time, record)]
    assert path.read_text().splitlines() == expected
    assert writer.stats.written == 2
    with pytest.raises(CommError, match="closed"):
        writer.write(["m x=1 1"])


_records = st.lists(
    st.one_of(
        st.tuples(st.just("line"), st.integers(0, 99)),
        st.tuples(st.just("record"), st.integers(0, 99)),
        st.tuples(st.just("flush"), st.just(0)),
    ),
    max_size=40,
)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(steps=_records, batch_size=st.integers(1, 5))
def test_the_file_has_every_line_in_the_order_written(tmp_path, steps, batch_size):
    # full batches are formatted by the writer that fills them, the rest by the writer's
    # thread at their deadline or on flush(): the file has the lines as written, in order
    path = tmp_path / f"order-{batch_size}-{len(steps)}.lp"
    expected: list[str] = []
    with InfluxWriter.to_file(path, append=False, batch_size=batch_size,
                              flush_interval=0.01) as writer:
        for kind, i in steps:
            if kind == "line":
                writer.write([f"m x={i} {i}"])
                expected.append(f"m x={i} {i}")
            elif kind == "record":
                record = {"stage": "plan", "duration": i / 10} if i % 2 else {"speed": i}
                writer.write_record(float(i), record)
                expected.extend(record_to_points(float(i), record))
            else:
                assert writer.flush(timeout=10)
    assert path.read_text().splitlines() == expected
    assert writer.stats.written == len(expected) and writer.stats.failed == 0


def test_formatted_batches_waiting_for_the_server_count_in_the_bounded_queue():
    server = _HeldServer()
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}"
        writer = InfluxWriter(url, "db", batch_size=2, max_queue=10)
        writer.write(["m x=1 1", "m x=2 2"])  # a full batch, taken and held by the server
        assert server.arrived.wait(10)
        accepted = sum(writer.write([f"m x={i} {i}"]) for i in range(3, 33))
        assert (accepted, writer.stats.dropped, writer.pending) == (10, 20, 10)
        server.release.set()
        writer.close()
        assert writer.stats.written == 12
    finally:
        server.release.set()
        server.shutdown()
        server.server_close()


def test_bad_configuration_is_refused():
    with pytest.raises(CommError, match="http://HOST:PORT"):
        InfluxWriter("influx://somewhere", "db")
    with pytest.raises(CommError, match="database name"):
        InfluxWriter("http://127.0.0.1:8086", "")
