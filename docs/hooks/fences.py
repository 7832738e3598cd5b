"""MkDocs hook (``mkdocs.yml``: ``hooks:``): the docs' fence markers, read by the doc-block tests
(``tests/docs/blocks.py``), become what the site's Markdown reads. ``python norun`` is shown as
``python``; ``python file=NAME`` as ``python`` titled with the file's name; ``text output`` as
``text``."""

from __future__ import annotations

import re
from typing import Any

#: an opening fence with words after its language
FENCE = re.compile(r"^(?P<indent>[ \t]*)```(?P<lang>[\w+-]+)[ \t]+(?P<words>[^`\n]+)$", re.M)


def info_string(lang: str, words: str) -> str:
    """What the site's fence says for a docs fence ``lang words``: the language, and the name of
    the file the block is (``file=NAME``) as its title."""
    for word in words.split():
        if word.startswith("file="):
            return f'{lang} title="{word.removeprefix("file=")}"'
    return lang


def on_page_markdown(markdown: str, **_: Any) -> str:
    return FENCE.sub(lambda m: f"{m['indent']}```{info_string(m['lang'], m['words'])}", markdown)
