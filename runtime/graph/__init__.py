"""Graph files: loading with source locations, checking, planning."""
