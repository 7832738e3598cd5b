"""Pan-tilt units that carry the Active Sketch cameras (simulated), and aiming them."""
