"""rmw_zenoh's wire format against its own design document's examples (ros2/rmw_zenoh,
``docs/design.md``: "Topic and Service name mapping", "Graph Cache", "Publishers") and against
hashes ROS 2 Jazzy itself prints (``ros2 topic info -v``)."""

from __future__ import annotations

import pytest

from umbra.runtime.ros2.attachment import ATTACHMENT_BYTES, Attachment
from umbra.runtime.ros2.keys import Endpoint, EntityKind, Node, data_key, parse_token
from umbra.runtime.ros2.msgtypes import known_type_problem, type_hash
from umbra.runtime.ros2.names import dds_type_name, ros_type_name, topic_name_problem
from umbra.runtime.ros2.qos import SENSOR_DATA, QosProfile, Reliability

# The design document's examples, verbatim.
CHATTER_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
DOC_CHATTER_KEY = f"0/chatter/std_msgs::msg::dds_::String_/{CHATTER_HASH}"
DOC_ROBOT1_KEY = f"0/robot1/chatter/std_msgs::msg::dds_::String_/{CHATTER_HASH}"
DOC_LISTENER_NODE = "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DOC_LISTENER_SUB = (
    "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
    f"std_msgs::msg::dds_::String_/{CHATTER_HASH}/::,10:,:,:,,"
)
DOC_TALKER_PUB = (
    "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
    f"std_msgs::msg::dds_::String_/{CHATTER_HASH}/::,7:,:,:,,"
)
# As `ros2 topic info -v` prints them on Jazzy.
JAZZY_HASHES = {
    "sensor_msgs/msg/Image": (
        "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"
    ),
    "sensor_msgs/msg/JointState": (
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
    ),
}


def test_chatter_key_is_the_design_documents():
    h = type_hash("std_msgs/msg/String")
    assert h == CHATTER_HASH
    assert data_key(0, "/chatter", "std_msgs/msg/String", h) == DOC_CHATTER_KEY
    assert data_key(0, "/robot1/chatter", "std_msgs/msg/String", h) == DOC_ROBOT1_KEY


@pytest.mark.parametrize("ros_type", sorted(JAZZY_HASHES))
def test_type_hashes_are_what_jazzy_prints(ros_type):
    assert type_hash(ros_type, "jazzy") == JAZZY_HASHES[ros_type]
    assert type_hash(ros_type, "kilted") == JAZZY_HASHES[ros_type]


def test_node_and_endpoint_tokens_are_the_design_documents():
    listener = Node(
        domain=2, session="aac3178e146ba6f1fc6e6a4085e77f21", node_id=0, name="listener"
    )
    talker = Node(domain=2, session="8b20917502ee955ac4476e0266340d5c", node_id=0, name="talker")
    sub = Endpoint(
        listener,
        10,
        EntityKind.SUBSCRIPTION,
        "/chatter",
        "std_msgs/msg/String",
        CHATTER_HASH,
        QosProfile(depth=10),
    )
    pub = Endpoint(
        talker,
        10,
        EntityKind.PUBLISHER,
        "/chatter",
        "std_msgs/msg/String",
        CHATTER_HASH,
        QosProfile(depth=7),
    )
    assert listener.token() == DOC_LISTENER_NODE
    assert sub.token() == DOC_LISTENER_SUB
    assert pub.token() == DOC_TALKER_PUB


def test_tokens_parse_back():
    node = parse_token(DOC_LISTENER_NODE)
    assert (node.kind, node.domain, node.node_name, node.namespace, node.enclave) == (
        EntityKind.NODE,
        2,
        "listener",
        "/",
        "",
    )
    pub = parse_token(DOC_TALKER_PUB)
    assert pub.kind is EntityKind.PUBLISHER
    assert (pub.topic, pub.ros_type, pub.type_hash) == (
        "/chatter",
        "std_msgs/msg/String",
        CHATTER_HASH,
    )
    assert pub.qos == QosProfile(depth=7)
    assert pub.node_fqn == "/talker"
    namespaced = Node(0, "abc", 3, "cam", namespace="/robot1")
    ep = Endpoint(
        namespaced,
        4,
        EntityKind.PUBLISHER,
        "/robot1/image",
        "sensor_msgs/msg/Image",
        type_hash("sensor_msgs/msg/Image"),
        SENSOR_DATA,
    )
    assert ep.token().split("/")[7:10] == ["%robot1", "cam", "%robot1%image"]
    back = parse_token(ep.token())
    assert (back.namespace, back.topic, back.node_fqn, back.qos) == (
        "/robot1",
        "/robot1/image",
        "/robot1/cam",
        SENSOR_DATA,
    )


@pytest.mark.parametrize(
    "key, why",
    [
        ("@ros2_lv/0/abc/0/0/XX/%/%/n", "unknown entity kind"),
        ("@ros2_lv/0/abc/0/0/NN/%/%", "9 or 13 chunks"),
        ("@ros2_lv/x/abc/0/0/NN/%/%/n", "domain number"),
        (DOC_TALKER_PUB.rsplit("/", 1)[0], "13 chunks"),
        (DOC_TALKER_PUB.rsplit("/", 1)[0] + "/::,7:,:", "6 `:`-separated"),
    ],
)
def test_malformed_tokens_are_refused_with_the_reason(key, why):
    with pytest.raises(ValueError, match=why):
        parse_token(key)


def test_qos_compact_form():
    assert QosProfile(depth=10).encode() == "::,10:,:,:,,"
    assert QosProfile().encode() == "::,:,:,:,,"
    assert SENSOR_DATA.encode() == "2::,5:,:,:,,"
    assert QosProfile.decode("2::,5:,:,:,,") == SENSOR_DATA
    assert QosProfile.decode("2::,5:,:,:,,").reliability is Reliability.BEST_EFFORT
    odd = QosProfile(deadline=(1, 500), lease=(3, 0))
    assert odd.encode() == "::,:1,500:,:,3,0"
    assert QosProfile.decode(odd.encode()) == odd


def test_attachment_bytes():
    gid = bytes(range(16))
    att = Attachment(seq=1, stamp_ns=0x0102030405060708, gid=gid)
    wire = att.encode()
    assert len(wire) == ATTACHMENT_BYTES == 33
    assert wire == bytes.fromhex(
        "0100000000000000080706050403020110000102030405060708090a0b0c0d0e0f"
    )
    assert Attachment.decode(wire) == att


def test_attachment_agrees_with_an_independent_decoder():
    zenoh_ros2_sdk = pytest.importorskip("zenoh_ros2_sdk.attachment")
    att = Attachment(seq=42, stamp_ns=1_750_000_000_123_456_789, gid=bytes(range(100, 116)))
    theirs = zenoh_ros2_sdk.Attachment.from_bytes(att.encode())
    assert (theirs.sequence_id, theirs.timestamp_ns, theirs.gid) == (att.seq, att.stamp_ns, att.gid)
    mine = Attachment.decode(zenoh_ros2_sdk.Attachment(7, 123, bytes(16)).to_bytes())
    assert (mine.seq, mine.stamp_ns) == (7, 123)


@pytest.mark.parametrize(
    "data, why",
    [
        (None, "found none"),
        (bytes(32), "33-byte"),
        (bytes(16) + bytes([24]) + bytes(24), "33-byte"),
        (bytes(16) + bytes([15]) + bytes(16), "length byte of 16, found 15"),
    ],
)
def test_attachment_refusals_say_what_was_found(data, why):
    with pytest.raises(ValueError, match=why):
        Attachment.decode(data)


@pytest.mark.parametrize(
    "name, why",
    [
        ("joint_states", "absolute"),
        ("/joint_states/", "end with"),
        ("/", "end with"),
        ("/a//b", "`//`"),
        ("/2cam/image", "digit"),
        ("/cam-1/image", "letters, digits"),
        ("/" + "a" * 247, "at most 247"),
        (7, "fully qualified"),
    ],
)
def test_bad_topic_names_say_why(name, why):
    problem = topic_name_problem(name)
    assert problem is not None and why in problem


def test_good_topic_names_and_type_names():
    assert topic_name_problem("/wrist_camera/image_raw") is None
    assert topic_name_problem("/_hidden/tf") is None
    assert dds_type_name("std_msgs/msg/String") == "std_msgs::msg::dds_::String_"
    assert ros_type_name("sensor_msgs::msg::dds_::Image_") == "sensor_msgs/msg/Image"
    assert ros_type_name("example_interfaces::srv::dds_::AddTwoInts_") is None
    assert known_type_problem("sensor_msgs/msg/JointState") is None
    assert "no message type" in known_type_problem("sensor_msgs/msg/JointStates")
    assert "package/msg/Name" not in known_type_problem("sensor_msgs/JointState")
    assert "like `sensor_msgs/msg/JointState`" in known_type_problem("sensor_msgs/JointState")
