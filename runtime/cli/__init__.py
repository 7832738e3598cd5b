"""The `umbra` command line: one file per sub-command (``cmd_<name>.py``)."""
