"""Vision: the statistical pressure snake, its features and sanity checks, a simulated camera."""
