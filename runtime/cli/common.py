"""Re-export of the CLI helpers (they live in ``umbra.connectors.cli_support`` so that domain
commands in ``modules`` can use them without importing the runtime)."""

from umbra.connectors.cli_support import parse_module_set, parse_set, parse_value, print_json

__all__ = ["parse_module_set", "parse_set", "parse_value", "print_json"]
