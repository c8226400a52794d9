"""The fleet in ROS 2: live topics in rmw_zenoh's format on the run's router (:mod:`.bridge`) and a rosbag2 of
a recording (:mod:`.export`), both built from one fold of the bus's messages (:mod:`.fold`). The message types,
their CDR encoding and their RIHS01 type hashes come from the ``rosbags`` package (the ``ros2`` extra)."""
