"""The pure half of ins_fusion_node (no rclpy): ROS messages <-> engine types and what the node
says and broadcasts, shared by the node and ``gnss_ins replay``.

- ``messages_in``: incoming messages (rclpy or rosbags objects) -> engine inputs;
- ``cdr_fields``: the few fields needed, straight from serialized (CDR) bytes;
- ``solution_out``: the fused solution -> nav_msgs/Odometry and NavSatFix fields;
- ``tf_frames``: the frames the node broadcasts and its static sensor transforms;
- ``status_log``: engine statuses -> rate-limited console lines.
"""
