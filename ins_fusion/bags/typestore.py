"""The rosbags typestore of the bags gnss_ins reads and writes: ROS 2 Jazzy's messages and the
ones rosbags' store lacks (corrections, NMEA sentences, serial chunks)."""

from __future__ import annotations

from functools import cache

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

#: Messages that rosbags' Jazzy store lacks, as their packages define them (the same fields as
#: ros_interfaces/, which builds them for rclpy): the ROS ecosystem's corrections and NMEA
#: sentences, and gnss_ins_msgs' serial chunks (a device's reads with their times: imu/raw).
EXTRA_MESSAGES = {
    "rtcm_msgs/msg/Message": "std_msgs/Header header\nuint8[] message\n",
    "nmea_msgs/msg/Sentence": "std_msgs/Header header\nstring sentence\n",
    "gnss_ins_msgs/msg/SerialChunk": (
        "std_msgs/Header header\nuint8 DATA=0\nuint8 OPENED=1\nuint8 STARTED=2\n"
        "uint8 event\nuint8[] data\nuint32[] read_ends\nint64[] read_times_ns\n"
    ),
}


@cache
def jazzy_typestore() -> Typestore:
    """The rosbags typestore of ROS 2 Jazzy (common_interfaces, rosgraph_msgs, ...) with
    EXTRA_MESSAGES."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in EXTRA_MESSAGES.items():
        store.register(get_types_from_msg(text, name))
    return store
