"""ROS 2 on the wire, without ROS: the rmw_zenoh format (keys, liveliness tokens, attachments,
CDR payloads), conversions between umbra's messages and ROS 2 messages, and a bridge that makes a
graph's mapped outputs and inputs appear to ROS 2 as an rmw_zenoh node's would (``docs/ros2.md``).
"""
