"""Fixtures of the introspection tests: those of the link tests (probe modules, ``umbra``)."""

from tests.links.conftest import plugin_env, umbra  # noqa: F401
