"""Active Sketch (LDRD report section 3): stereo primitives, motion macros and their planners."""
