"""Arm kinematics (DH tables, Jacobian, damped least squares), simulated joints, the velocity
register, and the servo-side modules (REG_VEL, ROTATE_KIN, WOLVERINE_KIN, WOLVERINE_JNTS)."""
