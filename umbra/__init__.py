"""umbra-smart's one installed top-level package.

The layout keeps three folders, installed under this package so that no other distribution's
names can collide with ours: ``connectors/`` is ``umbra.connectors`` (the base layer),
``modules/`` is ``umbra.modules`` (the domains) and ``runtime/`` is ``umbra.runtime`` (graphs,
scheduler, links, CLI); ``setup.py`` maps them (``docs/code-map.md``).
"""
