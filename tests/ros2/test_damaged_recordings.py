"""Damaged recordings are read for what they still hold, and what they lost is reported: random
bytes in an MCAP chunk (written by the mcap library, with CRCs, and by rosbags, without), a cut
MCAP file, damaged and cut SQLite3 files. A verdict that depended on what was lost is not
"satisfied": ``rasm check`` exits 1 unless ``--allow-damaged``."""

from __future__ import annotations

import json
import random
import shutil
import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from rasm.cli import main
from rasm.mcapfile import McapReader
from rasm.ros2 import BagReader, BagWriter, TypeStore

STORE = TypeStore()
FLOAT = STORE.codec("std_msgs/msg/Float64")
T0 = 1_700_000_000_000_000_000  # ns
STEP = 10_000_000  # 100 messages a second
VIOLATION = 15_000  # the one message above the limit
PROPS = "input x: float\nproperty low: always (x < 0.5)\n"
TOPICS = ("probes:\n  - topic: /x\n    type: std_msgs/msg/Float64\n    signals:\n"
          "      x: {field: data, type: float}\n")
COMPRESSIONS = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4,
                "zstd": CompressionType.ZSTD}


def value(i: int) -> float:
    return 1.0 if i == VIOLATION else 0.0


def mcap_with_crcs(path: Path, count: int = 20_000, compression: str = "zstd",
                   chunk_size: int = 64 * 1024) -> Path:
    """A rosbag2 MCAP of ``count`` Float64 messages on /x (and a /y every 10th), written the way
    rosbag2 writes one: chunked, CRCs, message indexes, a summary."""
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=chunk_size, compression=COMPRESSIONS[compression])
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema("std_msgs/msg/Float64", "ros2msg", b"float64 data")
        x = writer.register_channel("/x", "cdr", schema)
        y = writer.register_channel("/y", "cdr", schema)
        for i in range(count):
            t = T0 + i * STEP
            writer.add_message(x, t, FLOAT.encode({"data": value(i)}), t)
            if i % 10 == 0:
                writer.add_message(y, t + 1, FLOAT.encode({"data": 0.0}), t + 1)
        writer.finish()
    return path


def rosbags_bag(folder: Path, storage: str, count: int = 20_000) -> Path:
    """The same messages on /x written by rosbags (BagWriter): no CRCs in its MCAP chunks."""
    with BagWriter(folder, storage=storage) as writer:
        writer.add_topic("/x", "std_msgs/msg/Float64")
        for i in range(count):
            writer.write("/x", T0 + i * STEP, {"data": value(i)})
    return folder / f"{folder.name}{'.mcap' if storage == 'mcap' else '.db3'}"


def chunks(path: Path) -> list[tuple[int, int, int, int, int]]:
    """Each chunk: where its (compressed) records start and end, its time range, its offset."""
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    found = []
    for index in summary.chunk_indexes:
        head = index.chunk_start_offset + 9 + 8 + 8 + 8 + 4
        data = head + 4 + len(index.compression) + 8
        found.append((data, data + index.compressed_size, index.message_start_time,
                      index.message_end_time, index.chunk_start_offset))
    return found


def spoil(path: Path, offset: int, count: int, seed: int = 1) -> None:
    """Overwrite ``count`` bytes at ``offset`` with random bytes that differ from them."""
    rng = random.Random(seed)
    data = bytearray(path.read_bytes())
    for k in range(offset, min(offset + count, len(data))):
        data[k] = (data[k] + 1 + rng.randrange(255)) % 256
    path.write_bytes(bytes(data))


def check(tmp_path: Path, capsys, recording: Path, *extra: str) -> tuple[int, dict, str]:
    props = tmp_path / "p.rv"
    props.write_text(PROPS)
    topics = tmp_path / "topics.yaml"
    topics.write_text(TOPICS)
    code = main(["check", str(props), str(recording), "--topics", str(topics), "--format", "json",
                 *extra])
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


def chunk_holding(path: Path, time_ns: int) -> tuple[int, int, int, int, int]:
    return next(c for c in chunks(path) if c[2] <= time_ns <= c[3])


# ----------------------------------------------------------------------------- MCAP chunks


@pytest.mark.parametrize("compression", sorted(COMPRESSIONS))
def test_random_bytes_in_a_chunk_lose_that_chunk_reported_and_the_verdict_is_not_satisfied(
        tmp_path, capsys, compression):
    bag = mcap_with_crcs(tmp_path / "bag.mcap", compression=compression)
    start, end, first, last, offset = chunk_holding(bag, T0 + VIOLATION * STEP)
    spoil(bag, (start + end) // 2, 200)
    with McapReader(bag) as reader:
        read = list(reader.messages())
        (damage,) = reader.damage
    # every message of the other chunks is read, none of the spoilt one
    x_lost = sum(1 for i in range(20_000) if first <= T0 + i * STEP <= last)
    y_lost = sum(1 for i in range(0, 20_000, 10) if first <= T0 + i * STEP + 1 <= last)
    assert damage.messages == x_lost + y_lost and len(read) == 22_000 - damage.messages
    assert (damage.start_ns, damage.end_ns, damage.topics) == (first, last, ("/x", "/y"))
    assert damage.where == f"chunk at byte {offset:,}"
    assert not any(first <= t <= last for _, t, _ in read)

    code, report, err = check(tmp_path, capsys, bag)
    assert code == 1
    (prop,) = report["properties"]
    # the violation was in the lost chunk: nothing false was read, but it is not satisfied
    assert prop["verdict"] == "inconclusive" and prop["lost_data"] is True
    assert report["records"] == 20_000 - x_lost
    (lost,) = report["damage"]
    assert lost["messages"] == x_lost + y_lost and lost["topics"] == ["/x", "/y"]
    assert lost["from"] == pytest.approx(first / 1e9) and lost["to"] == pytest.approx(last / 1e9)
    assert "damaged:" in err and "--allow-damaged" in err

    code, report, _ = check(tmp_path, capsys, bag, "--allow-damaged")
    assert code == 0 and report["properties"][0]["verdict"] == "inconclusive"


def test_damage_on_a_topic_the_properties_do_not_read_changes_nothing(tmp_path, capsys):
    # a chunk holding only /y: write /y alone in its own chunks by giving it its own file part
    path = tmp_path / "bag.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=4096, compression=CompressionType.NONE)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema("std_msgs/msg/Float64", "ros2msg", b"float64 data")
        x = writer.register_channel("/x", "cdr", schema)
        y = writer.register_channel("/y", "cdr", schema)
        for i in range(2_000):
            writer.add_message(x, T0 + i * STEP, FLOAT.encode({"data": 0.0}), T0 + i * STEP)
        for i in range(2_000):
            t = T0 + 3_000 * STEP + i * STEP
            writer.add_message(y, t, FLOAT.encode({"data": 0.0}), t)
        writer.finish()
    start, end, *_ = chunks(path)[-1]  # /y only
    spoil(path, start + 10, 50)
    code, report, err = check(tmp_path, capsys, path)
    assert code == 0 and report["properties"][0]["verdict"] == "satisfied"
    assert "damage" not in report and "damaged" not in err


@pytest.mark.slow
@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_whatever_bytes_a_chunk_loses_each_message_is_read_intact_or_counted_lost(tmp_path, data):
    # with CRCs, any change inside a chunk's records loses exactly that chunk, counted
    bag = tmp_path / "bag.mcap"
    if not bag.exists():
        mcap_with_crcs(bag, count=3_000, compression="none", chunk_size=8 * 1024)
    spoilt = tmp_path / "spoilt.mcap"
    shutil.copy(bag, spoilt)
    found = chunks(bag)
    start, end, first, last, _ = data.draw(st.sampled_from(found))
    offset = data.draw(st.integers(start, end - 1))
    spoil(spoilt, offset, data.draw(st.integers(1, 300)), seed=data.draw(st.integers(0, 9)))
    original = {(t, d) for _, t, d in McapReader(bag).messages()}
    with McapReader(spoilt) as reader:
        read = list(reader.messages())
        damage = reader.damage
    assert {(t, d) for _, t, d in read} <= original
    assert len(read) + sum(d.messages for d in damage) == len(original)
    assert [(d.start_ns, d.end_ns) for d in damage] == [(first, last)]


def test_the_issues_bag_random_bytes_in_a_rosbags_chunk_are_not_satisfied(tmp_path, capsys):
    # rosbags writes no CRC: the damage is found by the records that no longer fit
    bag = rosbags_bag(tmp_path / "bag", "mcap")
    data = bag.read_bytes()
    at = data.find(FLOAT.encode({"data": 1.0}))  # the violating message's bytes
    assert at > 0
    spoil(bag, at - 100, 200)
    code, report, err = check(tmp_path, capsys, bag)
    assert code == 1
    assert report["properties"][0]["verdict"] != "satisfied"
    (lost,) = report["damage"]
    assert lost["where"].startswith("chunk at byte") and lost["messages"] == 20_000 - report[
        "records"]
    assert "rosbags" not in err


# ----------------------------------------------------------------------------- cut MCAP files


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.05, 0.999))
def test_a_cut_mcap_gives_the_chunks_before_the_cut_and_says_the_rest_is_lost(tmp_path, fraction):
    bag = tmp_path / "bag.mcap"
    if not bag.exists():
        mcap_with_crcs(bag, count=3_000, compression="lz4", chunk_size=8 * 1024)
    whole = bag.read_bytes()
    cut = tmp_path / "cut.mcap"
    size = int(len(whole) * fraction)
    cut.write_bytes(whole[:size])
    with bag.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    whole_chunks = [(c.message_start_time, c.message_end_time) for c in summary.chunk_indexes
                    if c.chunk_start_offset + c.chunk_length <= size]
    expected = {(t, d) for _, t, d in McapReader(bag).messages()
                if any(a <= t <= b for a, b in whole_chunks)}
    with McapReader(cut) as reader:
        read = [(t, d) for _, t, d in reader.messages()]
        damage = reader.damage
    assert set(read) == expected and len(read) == len(expected)
    everything = sum(1 for _ in McapReader(bag).messages())
    if len(read) == everything and not damage:
        return  # cut past the end of the data (its DataEnd record was read): nothing is lost
    (lost,) = damage  # one place: the cut record, or the end where the summary is missing
    assert lost.where.startswith(("a chunk at byte", "the end of the file", "a "))
    if read and lost.start_ns is not None:
        assert lost.start_ns >= max(t for t, _ in read) or lost.where.startswith("a chunk")


def test_a_recording_cut_before_its_first_chunk_ends_says_so(tmp_path, capsys):
    bag = rosbags_bag(tmp_path / "bag", "mcap", count=5_000)
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 2])
    props = tmp_path / "p.rv"
    props.write_text(PROPS)
    topics = tmp_path / "topics.yaml"
    topics.write_text(TOPICS)
    assert main(["check", str(props), str(bag), "--topics", str(topics)]) == 2
    err = capsys.readouterr().err
    assert "it is damaged" in err and "the file ends inside it" in err


# ----------------------------------------------------------------------------- SQLite3


def page_holding(db3: Path, content: bytes) -> int:
    """The byte offset of the SQLite page holding ``content``."""
    data = db3.read_bytes()
    size = struct.unpack(">H", data[16:18])[0]
    size = 65536 if size == 1 else size
    at = data.find(content)
    assert at > 0
    return at - at % size


@pytest.mark.slow
def test_damaged_sqlite_pages_lose_their_rows_counted_with_their_times(tmp_path, capsys):
    db3 = rosbags_bag(tmp_path / "bag", "sqlite3")
    at = page_holding(db3, FLOAT.encode({"data": 1.0}))  # the violation's page
    data = bytearray(db3.read_bytes())
    data[at:at + 12] = b"\xff" * 12  # the page header: its cells can no longer be found
    db3.write_bytes(bytes(data))
    code, report, err = check(tmp_path, capsys, db3)
    assert code == 1
    assert report["properties"][0]["verdict"] == "inconclusive"  # the violation was lost
    lost = report["damage"]
    assert sum(d["messages"] for d in lost) == 20_000 - report["records"] > 0
    # the time range around the run of lost rows holds the violation's time
    assert any(d["from"] < (T0 + VIOLATION * STEP) / 1e9 < d["to"] for d in lost)
    assert "SQLite reports the file damaged" in err
    code, _, _ = check(tmp_path, capsys, db3, "--allow-damaged")
    assert code == 0


@pytest.mark.slow
def test_a_cut_sqlite_file_reads_up_to_the_cut_and_says_the_rest_is_lost(tmp_path, capsys):
    db3 = rosbags_bag(tmp_path / "bag", "sqlite3")
    data = db3.read_bytes()
    db3.write_bytes(data[: len(data) // 2])
    code, report, _ = check(tmp_path, capsys, db3)
    assert code == 1 and 0 < report["records"] < 20_000
    (lost,) = report["damage"]
    assert lost["messages"] is None and lost["where"].startswith("the message rows from")
    read_to = T0 + (report["records"] - 1) * STEP
    assert lost["from"] == pytest.approx(read_to / 1e9)


def test_a_sound_recording_reports_no_damage(tmp_path, capsys):
    for storage in ("mcap", "sqlite3"):
        bag = rosbags_bag(tmp_path / storage, storage, count=2_000)
        code, report, err = check(tmp_path, capsys, bag)
        assert code == 0 and "damage" not in report and "damaged" not in err
        assert BagReader(bag).damage == []


def test_a_replay_of_a_damaged_recording_fails_the_run_and_says_what_was_lost(tmp_path, capsys):
    from tests.ros2.conftest import DATA

    app = DATA / "guard"
    bag = tmp_path / "bag.mcap"
    with bag.open("wb") as stream:
        writer = Writer(stream, chunk_size=4096, compression=CompressionType.NONE)
        writer.start(profile="ros2", library="test")
        odom = STORE.codec("nav_msgs/msg/Odometry")
        schema = writer.register_schema("nav_msgs/msg/Odometry", "ros2msg", b"")
        channel = writer.register_channel("/odom", "cdr", schema)
        for i in range(400):
            t = T0 + i * 10 * STEP
            stamp = {"sec": t // 10**9, "nanosec": t % 10**9}
            writer.add_message(channel, t, odom.encode({
                "header": {"stamp": stamp}, "twist": {"twist": {"linear": {"x": 0.1}}}}), t)
        writer.finish()
    start, end, *_ = chunks(bag)[1]
    spoil(bag, start + 40, 100)
    trace = tmp_path / "replay.jsonl"
    code = main(["run", str(app), "--replay", str(bag), "--trace", str(trace)])
    out = capsys.readouterr().out
    assert code == 1
    assert "damaged recording" in out and "chunk at byte" in out

