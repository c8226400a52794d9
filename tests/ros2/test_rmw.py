"""rmw_zenoh's format (ros2/rmw.py) and the type hashes (ros2/types.py), checked against rmw_zenoh's design
document and a client nobody here wrote, ``zenoh-ros2-sdk`` (its key, attachment, token and QoS code, and its own
RIHS01 hash computed from ``.msg`` text)."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("rosbags")
sdk = pytest.importorskip("zenoh_ros2_sdk")

from zenoh_ros2_sdk import keyexpr as sdk_keys  # noqa: E402
from zenoh_ros2_sdk.attachment import Attachment  # noqa: E402
from zenoh_ros2_sdk.entity import EndpointEntity, EntityKind, NodeEntity  # noqa: E402
from zenoh_ros2_sdk.qos import QosDurability, QosProfile  # noqa: E402
from zenoh_ros2_sdk.utils import get_type_hash, ros2_to_dds_type  # noqa: E402

from fleet_emu.ros2 import rmw  # noqa: E402
from fleet_emu.ros2.fold import topics  # noqa: E402
from fleet_emu.ros2.types import GRID, type_hash  # noqa: E402

# rmw_zenoh's docs/design.md at commit 99a6a2bd10b949052f4f12c5854825dc005e95a5, its demo_nodes_cpp examples,
# verbatim ("Topic and Service name mapping to Zenoh key expressions" and "Graph Cache"); its "Publishers" section
# lays out the attachment: int64 sequence number and int64 timestamp (ns), little-endian, one length byte (16), the
# 16-byte GID
DESIGN_STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
DESIGN_KEY = f"0/robot1/chatter/std_msgs::msg::dds_::String_/{DESIGN_STRING_HASH}"
DESIGN_NODE = "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DESIGN_TALKER = ("@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/"
                 f"{DESIGN_STRING_HASH}/::,7:,:,:,,")


def test_the_design_documents_examples() -> None:
    """The hash, the key expression and the tokens of rmw_zenoh's own examples, built here."""
    string = "std_msgs/msg/String"
    assert type_hash(string) == DESIGN_STRING_HASH
    assert rmw.topic_key(0, "/robot1/chatter", string, type_hash(string)) == DESIGN_KEY
    assert rmw.node_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "listener") == DESIGN_NODE
    assert rmw.publisher_token(2, "8b20917502ee955ac4476e0266340d5c", 0, 10, "talker", "/chatter", string,
                               type_hash(string), rmw.qos(False, depth=7)) == DESIGN_TALKER


@pytest.mark.parametrize("typename", sorted({t for t, _ in topics(2).values()}))
def test_keys_and_hashes_agree_with_the_sdk(typename: str, tmp_path: Path) -> None:
    """The SDK's own hash, computed from the .msg texts (rosbags' definitions written out), is rosbags'; its
    key expression and DDS type name are ours."""
    from docs.ros2.listen import write_msg_files

    write_msg_files(tmp_path, [typename])
    text = (tmp_path / f"{typename}.msg").read_text()
    deps = {str(p.relative_to(tmp_path).with_suffix("")): p.read_text() for p in tmp_path.rglob("*.msg")}
    deps.pop(typename)
    assert get_type_hash(typename, text, deps) == type_hash(typename)
    assert rmw.dds_type(typename) == ros2_to_dds_type(typename)
    assert rmw.topic_key(7, "/r0/map", typename, "H") == sdk_keys.topic_keyexpr(7, "/r0/map",
                                                                                 ros2_to_dds_type(typename), "H")


def test_the_attachment_is_33_bytes_the_sdk_reads() -> None:
    gid = bytes(range(16))
    data = rmw.attachment(5, 1_700_000_000_123_456_789, gid)
    assert len(data) == 33  # the design document's layout, field by field
    assert data[:8] == (5).to_bytes(8, "little") and data[8:16] == (1_700_000_000_123_456_789).to_bytes(8, "little")
    assert data[16] == 16 and data[17:] == gid
    got = Attachment.from_bytes(data)
    assert (got.sequence_id, got.timestamp_ns, got.gid) == (5, 1_700_000_000_123_456_789, gid)
    assert rmw.parse_attachment(Attachment(5, 9, gid).to_bytes()) == (5, 9, gid)
    with pytest.raises(ValueError):
        rmw.attachment(1, 1, b"short")


def test_tokens_are_the_sdks() -> None:
    node = NodeEntity(domain_id=3, session_id="abc", node_id=0, node_name="fleet_emu")
    assert rmw.node_token(3, "abc", 0, "fleet_emu") == sdk_keys.node_liveliness_keyexpr(node)
    h = type_hash(GRID)
    ep = EndpointEntity(node=node, entity_id=4, kind=EntityKind.PUBLISHER, name="/r1/map",
                        dds_type_name=ros2_to_dds_type(GRID), type_hash=h, qos=rmw.qos(True))
    assert rmw.publisher_token(3, "abc", 0, 4, "fleet_emu", "/r1/map", GRID, h, rmw.qos(True)) == \
        sdk_keys.endpoint_liveliness_keyexpr(ep)


@pytest.mark.parametrize("latched", [True, False])
def test_the_qos_field_decodes_as_meant(latched: bool) -> None:
    q = QosProfile.decode(rmw.qos(latched))
    assert q.history_depth == 1
    assert q.durability == (QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE)
