"""The simulated world of the tool pick-up: true tool pose, camera pose, grasp judge."""
