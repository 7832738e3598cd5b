"""Re-export of the user-facing error types (they live in ``umbra.connectors.errors`` so modules can
raise them without importing the runtime)."""

from umbra.connectors.errors import CheckFailed, Diagnostic, Location, ModuleFailed, UserError

__all__ = ["CheckFailed", "Diagnostic", "Location", "ModuleFailed", "UserError"]
