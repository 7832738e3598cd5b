"""Generic modules every dataflow tool has: sources, sinks, a recorder."""
