"""umbra-smart's one installed top-level package.

The layout keeps three folders, installed under this package so that no other distribution's
names can collide with ours: ``connectors/`` is ``umbra.connectors`` (the base layer),
``modules/`` is ``umbra.modules`` (the domains) and ``runtime/`` is ``umbra.runtime`` (graphs,
scheduler, links, CLI); ``setup.py`` maps them (``docs/code-map.md``).

The old top-level names (``import runtime``, ``from connectors import ...``) still import for a
deprecation period, as aliases with a DeprecationWarning, but never in place of a package of the
same name that is installed or on ``sys.path`` (``umbra.legacy_names``).
"""

from umbra.legacy_names import install_legacy_names

install_legacy_names()
