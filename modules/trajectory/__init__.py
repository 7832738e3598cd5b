"""Trajectory playback on the servo side: the VCR player of Active Sketch."""
