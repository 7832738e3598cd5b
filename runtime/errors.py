"""Re-export of the user-facing error types (they live in ``connectors.errors`` so modules can raise
them without importing the runtime)."""

from connectors.errors import CheckFailed, Diagnostic, Location, ModuleFailed, UserError

__all__ = ["CheckFailed", "Diagnostic", "Location", "ModuleFailed", "UserError"]
