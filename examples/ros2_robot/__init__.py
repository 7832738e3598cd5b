"""A small simulated ROS 2 robot (a Puma 560 with a wrist camera over the tool's tray) that
speaks ROS 2 only through ``zenoh-ros2-sdk``, an implementation of rmw_zenoh's wire independent
of umbra's: ``python -m examples.ros2_robot --router tcp/127.0.0.1:7447`` (docs/ros2.md)."""
