"""Image-moment visual servoing (vsServo): features, the 4-DOF law, goals and grab stages."""
