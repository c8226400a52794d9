"""rmw_zenoh's wire format (``rmw_zenoh_cpp``, Jazzy and later), pure functions: the key expression of a
topic, the attachment of a publication, the liveliness tokens of a node and its publishers, and the QoS string
those tokens carry. Followed from rmw_zenoh's ``docs/design.md`` at commit
99a6a2bd10b949052f4f12c5854825dc005e95a5 ("Topic and Service name mapping to Zenoh key expressions", "Graph
Cache", "Publishers", with their ``demo_nodes_cpp`` examples), and cross-checked with the third-party
``zenoh-ros2-sdk`` 0.1.8 (``keyexpr.py``, ``attachment.py``, ``qos.py``), which speaks it to ROS 2 nodes;
tests/ros2/test_rmw.py checks both.

- data: ``<domain>/<topic without its leading slash>/<DDS type name>/<RIHS01 type hash>``, CDR payload;
- attachment (33 bytes, little-endian): sequence number (int64), source timestamp (int64, ns), the GID's
  length (one byte, 16) and the publisher's 16-byte GID;
- liveliness: ``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>``
  (kind ``NN`` for the node, its entity id its node id), and for a publisher (``MP``) further
  ``/<mangled topic>/<DDS type name>/<type hash>/<QoS>``; a name is mangled by writing ``/`` as ``%`` (an
  empty name, the enclave, is ``%``).
"""

from __future__ import annotations

import struct

ADMIN_SPACE = "@ros2_lv"
GID_SIZE = 16


def dds_type(typename: str) -> str:
    """``nav_msgs/msg/OccupancyGrid`` -> ``nav_msgs::msg::dds_::OccupancyGrid_``."""
    package, kind, name = typename.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def mangle(name: str) -> str:
    return "%" if name in ("", "/") else name.replace("/", "%")


def topic_key(domain: int, topic: str, typename: str, type_hash: str) -> str:
    return f"{domain}/{topic.lstrip('/')}/{dds_type(typename)}/{type_hash}"


def attachment(seq: int, stamp_ns: int, gid: bytes) -> bytes:
    if len(gid) != GID_SIZE:
        raise ValueError(f"a GID has {GID_SIZE} bytes, not {len(gid)}")
    return struct.pack("<qqB", seq, stamp_ns, GID_SIZE) + gid


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp, GID) of an attachment; ValueError when it is not one."""
    if len(data) != 17 + GID_SIZE or data[16] != GID_SIZE:
        raise ValueError(f"not an rmw_zenoh attachment ({len(data)} bytes)")
    seq, stamp = struct.unpack_from("<qq", data)
    return seq, stamp, bytes(data[17:])


def qos(latched: bool, depth: int = 1) -> str:
    """The QoS field of a token as rmw_zenoh's ``qos_to_keyexpr`` writes it, a field equal to its default
    (reliable, volatile, keep last) left empty: keep last ``depth``, transient local (``1``) when ``latched``;
    the design document's talker publishes ``::,7:,:,:,,``."""
    return f":{'1' if latched else ''}:,{depth}:,:,:,,"


def node_token(domain: int, zid: str, node_id: int, name: str, namespace: str = "/") -> str:
    return f"{ADMIN_SPACE}/{domain}/{zid}/{node_id}/{node_id}/NN/%/{mangle(namespace)}/{name}"


def publisher_token(domain: int, zid: str, node_id: int, entity_id: int, name: str, topic: str, typename: str,
                    type_hash: str, qos_text: str, namespace: str = "/") -> str:
    return (f"{ADMIN_SPACE}/{domain}/{zid}/{node_id}/{entity_id}/MP/%/{mangle(namespace)}/{name}/"
            f"{mangle(topic)}/{dds_type(typename)}/{type_hash}/{qos_text}")
