"""rosbag2 recordings written by rosbags itself (and by BagWriter) read back by rasm.ros2.bags."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rasm.ros2 import BagError, BagReader, BagWriter, TypeStore, read_bag
from tests.ros2 import peer
from tests.ros2.conftest import CUSTOM_MSG_DIR
from tests.ros2.samples import SAMPLES, expected

STORE = TypeStore()
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}


def _record(path: Path, storage: str, start: int = 1_000, count: int = 5,
            typestore=peer.STORE, extra: tuple = ()) -> list[tuple[int, str, dict]]:
    """A bag of /odom and /scan messages written with rosbags alone; what it holds."""
    written = []
    with Writer(path, version=9, storage_plugin=STORAGES[storage]) as writer:
        connections = {
            topic: writer.add_connection(topic, SAMPLES[topic][0], typestore=typestore)
            for topic in ("/odom", "/scan", *extra)
        }
        for i in range(count):
            for offset, topic in enumerate(connections):
                typename, message = SAMPLES[topic]
                message = dict(message, header={"stamp": {"sec": i, "nanosec": offset},
                                                "frame_id": topic})
                data = typestore.serialize_cdr(peer.to_object(typename, message), typename)
                time_ns = start + 10 * i + offset
                writer.write(connections[topic], time_ns, bytes(data))
                written.append((time_ns, topic, message))
    return written


@pytest.mark.parametrize("storage", sorted(STORAGES))
@pytest.mark.parametrize("form", ["folder", "file"])
def test_bags_written_by_rosbags_are_read_in_log_time_order(tmp_path, storage, form):
    bag = tmp_path / "bag"
    written = _record(bag, storage)
    path = bag if form == "folder" else bag / f"bag{SUFFIX[storage]}"
    reader = BagReader(path)
    assert reader.topics == {"/odom": "nav_msgs/msg/Odometry",
                             "/scan": "sensor_msgs/msg/LaserScan"}
    assert reader.message_count == len(written)
    records = list(reader)
    assert [(r.time_ns, r.topic) for r in records] == [(t, topic) for t, topic, _ in written]
    for record, (_, topic, message) in zip(records, written, strict=True):
        assert record.message == expected(STORE, SAMPLES[topic][0], message)
    assert records[3].message["header"]["stamp"] == {"sec": 1, "nanosec": 1}


def test_a_topic_selection_reads_only_those_topics(tmp_path):
    _record(tmp_path / "bag", "mcap")
    records = list(read_bag(tmp_path / "bag", topics=["/scan"]))
    assert {r.topic for r in records} == {"/scan"} and len(records) == 5
    with pytest.raises(BagError, match="no topic /imu in this recording \\(it has /odom, /scan\\)"):
        BagReader(tmp_path / "bag", topics=["/imu"])


def test_a_folder_whose_metadata_qos_differs_from_its_storage_is_read_whole(tmp_path):
    bag = tmp_path / "bag"
    written = _record(bag, "mcap")
    meta = bag / "metadata.yaml"
    # as rosbag2's own test bags: the metadata's QoS text is not the one the storage holds
    forever = "{sec: 9223372036, nsec: 854775807}"
    meta.write_text(meta.read_text().replace("offered_qos_profiles: []", (
        "offered_qos_profiles:\n      - history: keep_last\n        depth: 7\n"
        "        reliability: reliable\n        durability: volatile\n"
        f"        deadline: {forever}\n        lifespan: {forever}\n"
        f"        liveliness: automatic\n        liveliness_lease_duration: {forever}\n"
        "        avoid_ros_namespace_conventions: false"
    )))
    with AnyReader([bag]) as trapped:  # the trap: rosbags yields nothing through the folder
        assert sum(1 for _ in trapped.messages()) == 0
    assert len(list(read_bag(bag))) == len(written)


def test_a_split_recording_is_merged_in_time_order(tmp_path):
    first = _record(tmp_path / "one", "mcap", start=1_000)
    second = _record(tmp_path / "two", "mcap", start=1_005)
    bag = tmp_path / "bag"
    bag.mkdir()
    shutil.copy(tmp_path / "one" / "one.mcap", bag / "bag_0.mcap")
    shutil.copy(tmp_path / "two" / "two.mcap", bag / "bag_1.mcap")
    meta = (tmp_path / "one" / "metadata.yaml").read_text()
    (bag / "metadata.yaml").write_text(
        meta.replace("relative_file_paths:\n  - one.mcap",
                     "relative_file_paths:\n  - bag_0.mcap\n  - bag_1.mcap")
    )
    times = [r.time_ns for r in read_bag(bag)]
    assert times == sorted(t for t, _, _ in first + second)


def test_a_type_the_store_lacks_is_decoded_from_the_bags_definition(tmp_path):
    typestore = get_typestore(Stores.ROS2_JAZZY)
    for path in CUSTOM_MSG_DIR.glob("*.msg"):
        definitions = get_types_from_msg(path.read_text(), f"rasm_demo/msg/{path.stem}")
        typestore.register(definitions)
        peer.STORE.register(definitions)
    written = _record(tmp_path / "bag", "sqlite3", typestore=typestore, extra=("/spin_plan",))
    assert "rasm_demo/msg/SpinPlan" not in STORE
    plans = [r for r in read_bag(tmp_path / "bag") if r.topic == "/spin_plan"]
    assert len(plans) == 5
    assert plans[0].message["skip_sectors"] == [False, True, False]
    assert plans[0].message["reason"] == "occluded"
    assert len(written) == 15


def test_undecodable_messages_are_skipped_and_counted(tmp_path, caplog):
    bag = tmp_path / "bag"
    good = STORE.codec("std_msgs/msg/Bool").encode({"data": True})
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        flag = writer.add_connection("/flag", "std_msgs/msg/Bool", typestore=STORE.rosbags)
        for i, data in enumerate([good, b"\x00\x01", good, b"junk" * 9, good]):
            writer.write(flag, i, data)
    reader = BagReader(bag)
    assert [r.message for r in reader] == [{"data": True}] * 3
    assert reader.rejected == 2
    assert len([r for r in caplog.records if r.name == "rasm.ros2.bags"]) == 1


@pytest.mark.parametrize("path", ["nowhere", "file.txt"])
def test_what_is_not_a_bag_is_refused(tmp_path, path):
    if path.endswith(".txt"):
        (tmp_path / path).write_text("hello")
    with pytest.raises(BagError, match=path):
        BagReader(tmp_path / path)


@pytest.mark.parametrize("storage", sorted(STORAGES))
def test_bags_written_by_rasm_are_read_by_rosbags(tmp_path, storage):
    bag = tmp_path / "trace"
    with BagWriter(bag, storage=storage) as writer:
        writer.add_topic("/cmd_vel", "geometry_msgs/msg/Twist")
        writer.add_topic("/flag", "std_msgs/msg/Bool")
        writer.write("/cmd_vel", 10, {"linear": {"x": 0.2}})
        writer.write("/flag", 20, {"data": True})
        with pytest.raises(BagError, match="/odom was not added"):
            writer.write("/odom", 30, {})
    with AnyReader([bag], default_typestore=STORE.rosbags) as reader:
        got = [(c.topic, t, reader.deserialize(d, c.msgtype)) for c, t, d in reader.messages()]
    assert [(topic, t) for topic, t, _ in got] == [("/cmd_vel", 10), ("/flag", 20)]
    assert got[0][2].linear.x == 0.2 and got[1][2].data is True
    if storage == "mcap":  # and by the MCAP library itself
        with open(bag / "trace.mcap", "rb") as stream:
            channels = {channel.topic: schema.name for schema, channel, _ in
                        make_reader(stream).iter_messages()}
        assert channels == {"/cmd_vel": "geometry_msgs/msg/Twist", "/flag": "std_msgs/msg/Bool"}


def test_a_topic_without_a_definition_is_left_out_unless_asked_for(tmp_path, caplog):
    # rosbag2 records service events as topics whose definitions rosbags cannot read; a
    # recording of them is read for its other topics
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        flag = writer.add_connection("/flag", "std_msgs/msg/Bool", typestore=STORE.rosbags)
        event = writer.add_connection("/add/_service_event", "demo_srvs/srv/Add_Event",
                                      msgdef="int64 a\n---\nint64 sum\n", rihs01="RIHS01_00")
        for i in range(3):
            writer.write(flag, 10 * i, STORE.codec("std_msgs/msg/Bool").encode({"data": True}))
            writer.write(event, 10 * i + 1, b"\x00\x01\x00\x00" + bytes(16))
    reader = BagReader(bag)
    assert [r.topic for r in reader] == ["/flag"] * 3
    assert set(reader.undecodable) == {"/add/_service_event"}
    assert "demo_srvs/srv/Add_Event" in caplog.text
    assert BagReader(bag, topics=["/flag"]).message_count == 3
    with pytest.raises(BagError, match="cannot decode topic /add/_service_event"):
        BagReader(bag, topics=["/add/_service_event"])
