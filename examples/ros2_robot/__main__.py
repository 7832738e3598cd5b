"""``python -m examples.ros2_robot``: the simulated ROS 2 robot (:mod:`.sim_robot`)."""

import sys

from examples.ros2_robot.sim_robot import main

sys.exit(main())
