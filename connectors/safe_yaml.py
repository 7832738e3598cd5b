"""YAML that cannot hurt the reader: bounded depth and alias expansion, no duplicate keys, every
failure ``FILE:LINE: error: ...``.

Every YAML file the project reads goes through :func:`compose` (node tree with line numbers) or
:func:`load` (plain Python values as well). Refused, each at its line:

* nesting deeper than ``max_depth`` (also after following aliases), and alias expansion to more
  than ``max_nodes`` nodes ("billion laughs") or onto itself (a recursive alias);
* a mapping key given twice (after YAML's own ``<<`` merges, later keys win as YAML says);
* values a tag cannot make (``!!float abc``, a 5000-digit integer, ``!!python/...`` tags);
* a mapping key that YAML 1.1 reads as a boolean (an unquoted ``off``, ``on``, ``yes``, ``no``,
  ``true``, ``false``...): no key of the project's files is a boolean, so it is a name that must
  be quoted. :func:`boolean_hint` says the same of a value found where a name was expected;
* a line end other than LF or CRLF (a lone CR, U+0085, U+2028, U+2029), which YAML counts as a
  line and an editor may not, and a tab or an invisible space (no-break, em, ideographic,
  zero-width...) where YAML expects an indentation of spaces (:func:`line_end_problem`,
  :func:`odd_indent`). So a position is the same for the reader as for an editor: line N is
  after the (N-1)th LF, column C is the C-th character of that line.

Merge keys (``<<: *base``) are YAML 1.1's: the mapping's own keys override merged ones, and of a
list of merged mappings (``<<: [*a, *b]``) an earlier one wins; a key written twice in the
mapping itself is refused.
"""

from __future__ import annotations

import re
import unicodedata
from typing import Any

import yaml

from umbra.connectors.errors import UserError

MAX_DEPTH = 64
MAX_NODES = 100_000
_MERGE_TAG = "tag:yaml.org,2002:merge"
_BOOL_TAG = "tag:yaml.org,2002:bool"
#: Line ends that YAML counts as a line and an editor may not: a CR without LF, NEL, LS, PS.
_ODD_LINE_END = re.compile(r"\r(?!\n)|[\x85\u2028\u2029]")
#: Characters that look like indentation and are not YAML's (a space): a tab, Unicode spaces,
#: zero-width spaces and joiners, a byte-order mark inside the text.
_ODD_SPACE = "\t\u00a0\u1680\u180e\u2000-\u200d\u202f\u205f\u2060\u3000\ufeff"
_ODD_INDENT = re.compile(f"^ *([{_ODD_SPACE}])", re.MULTILINE)


def boolean_hint(value: Any, text: str = "") -> str:
    """For a boolean found where a name or text was expected: a sentence saying YAML 1.1 read
    the unquoted word (``text`` when known, e.g. ``off``) as a boolean, and to quote it; else
    empty."""
    if not isinstance(value, bool):
        return ""
    word = f"`{text}`" if text else "an unquoted yes/no/on/off/true/false"
    quoted = f"'{text}'" if text else "'off'"
    return (
        f" (YAML 1.1 reads {word} as the boolean {str(value).lower()}: "
        f"quote it, as in {quoted}, to use it as a name)"
    )


class YamlError(UserError):
    """A YAML problem at ``line`` of ``source``; ``str()`` is ``SOURCE:LINE: error: MESSAGE``.
    ``syntax``: the text is not YAML at all (as against YAML that breaks a bound or has a bad
    value)."""

    def __init__(self, source: str, line: int, message: str, *, syntax: bool = False) -> None:
        self.source, self.line, self.message, self.syntax = source, line, message, syntax
        super().__init__(f"{source}:{line}: error: {message}")


def _invalid(source: str, line: int, problem: object) -> YamlError:
    """The text at ``line`` of ``source`` is not YAML: ``problem`` says why."""
    return YamlError(source, line, f"invalid YAML: {problem}", syntax=True)


class Refused(Exception):
    """Raised inside the reader: the document breaks a bound at ``line`` (and ``column``, both
    1-based)."""

    def __init__(self, line: int, message: str, column: int = 1) -> None:
        self.line, self.message, self.column = line, message, column


class BoundedLoader(yaml.SafeLoader):  # type: ignore[misc]  # PyYAML ships no type hints
    """A safe loader whose composer refuses nesting deeper than ``max_depth``."""

    def __init__(self, text: str, max_depth: int) -> None:
        super().__init__(text)
        self.depth, self.max_depth = 0, max_depth

    def compose_node(self, parent: Any, index: Any) -> Any:
        self.depth += 1
        try:
            if self.depth > self.max_depth:
                mark = self.peek_event().start_mark
                raise Refused(mark.line + 1, f"nesting deeper than {self.max_depth} levels")
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


def char_name(char: str) -> str:
    """``a no-break space (U+00A0)``: a character's Unicode name and code, for messages."""
    controls = {"\t": "tab", "\r": "carriage return", "\x85": "next line"}
    name = unicodedata.name(char, "").lower() or controls.get(char, "control character")
    article = "an" if name[:1] in "aeiou" else "a"
    return f"{article} {name} (U+{ord(char):04X})"


def _position(text: str, index: int) -> tuple[int, int]:
    """1-based ``(line, column)`` of ``text[index]``, lines counted by LF."""
    line_start = text.rfind("\n", 0, index) + 1
    return text.count("\n", 0, index) + 1, index - line_start + 1


def line_end_problem(text: str) -> Refused | None:
    """The first line end other than LF or CRLF, as a refusal at its position; None if none."""
    found = _ODD_LINE_END.search(text)
    if found is None:
        return None
    line, column = _position(text, found.start())
    return Refused(
        line,
        f"{char_name(found.group())} ends a line here: YAML counts it as a line end and an "
        "editor may not, so positions would disagree; save the file with LF or CRLF line ends",
        column,
    )


def odd_indent(text: str, last_line: int) -> Refused | None:
    """The last line up to ``last_line`` (1-based) whose indentation holds a tab or an invisible
    space, as a refusal at that character; None if none. Called when YAML failed at
    ``last_line``: such a character is not YAML indentation, so YAML reads it as text and fails
    on a later line, where the mistake is not."""
    found, line, counted = None, 1, 0
    for match in _ODD_INDENT.finditer(text):
        index = match.start(1)
        line += text.count("\n", counted, index)
        counted = index
        if line > last_line:
            break
        found = index
    if found is None:
        return None
    line, column = _position(text, found)
    return Refused(line, _indent_message(text[found]), column)


def _indent_message(char: str) -> str:
    return f"{char_name(char)} where YAML expects indentation: YAML indents with spaces only"


def compose(
    text: str, source: str, max_depth: int = MAX_DEPTH, max_nodes: int = MAX_NODES
) -> yaml.Node | None:
    """The node tree of one YAML document; :class:`YamlError` on any problem."""
    text = text.removeprefix("\ufeff")  # a byte-order mark is no character of line 1
    odd = line_end_problem(text)
    if odd is not None:
        raise YamlError(source, odd.line, odd.message)
    try:
        loader = BoundedLoader(text, max_depth)  # refuses unprintable characters at once
    except yaml.reader.ReaderError as exc:
        line = text[: exc.position].count("\n") + 1
        raise _invalid(source, line, _short(exc)) from None
    try:
        node = loader.get_single_node()
        if node is not None:
            check_tree(node, max_depth, max_nodes)
        return node
    except Refused as stop:
        raise YamlError(source, stop.line, stop.message) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        indent = odd_indent(text, mark.line + 1 if mark else 1)
        if indent is not None:
            raise _invalid(source, indent.line, indent.message) from None
        problem = exc.problem or exc.context or "not valid YAML"
        raise _invalid(source, mark.line + 1 if mark else 1, problem) from None
    except yaml.YAMLError as exc:
        raise _invalid(source, 1, str(exc).splitlines()[0]) from None
    except RecursionError:
        raise YamlError(source, 1, "YAML nesting is too deep") from None
    except Exception as exc:  # PyYAML itself failing on the text (`%YAML 1.<5000 digits>`)
        line = loader.get_mark().line + 1
        raise _invalid(source, line, _short(exc)) from None
    finally:
        loader.dispose()


def construct(node: yaml.Node | None, source: str) -> Any:
    """Plain Python values of a node tree from :func:`compose`; YamlError at the bad value."""
    if node is None:
        return None
    resolve_merges(node, set())
    loader = yaml.SafeLoader("")
    try:
        return loader.construct_document(node)
    except Exception as exc:  # any failure to build a value is the file's fault
        line, message = _first_bad_value(node, exc)
        raise YamlError(source, line, message) from None
    finally:
        loader.dispose()


def resolve_merges(node: yaml.Node, done: set[int]) -> None:
    """Replace the ``<<`` keys under ``node`` by the pairs they merge, as YAML 1.1 says: the
    mapping's own keys win, then an earlier merged mapping over a later one (PyYAML's own
    merge lets a later one win). A ``<<`` on something else than mappings is left for the
    constructor to refuse."""
    if id(node) in done:
        return
    done.add(id(node))
    for kid in _children(node):
        resolve_merges(kid, done)
    if not isinstance(node, yaml.MappingNode):
        return
    sources: list[yaml.MappingNode] = []
    for key, value in node.value:
        if key.tag == _MERGE_TAG:
            items = value.value if isinstance(value, yaml.SequenceNode) else [value]
            if not all(isinstance(item, yaml.MappingNode) for item in items):
                return
            sources.extend(items)
    if not sources:
        return
    own = [(key, value) for key, value in node.value if key.tag != _MERGE_TAG]
    taken = {_key_ident(key) for key, _value in own}
    merged = []
    for source in sources:
        for key, value in source.value:
            if _key_ident(key) not in taken:
                taken.add(_key_ident(key))
                merged.append((key, value))
    node.value = merged + own


def _key_ident(key: yaml.Node) -> Any:
    return (key.tag, key.value) if isinstance(key, yaml.ScalarNode) else id(key)


def load(text: str, source: str, max_depth: int = MAX_DEPTH) -> tuple[yaml.Node | None, Any]:
    """``(node tree, plain values)`` of one YAML document."""
    node = compose(text, source, max_depth)
    return node, construct(node, source)


def _line(node: yaml.Node) -> int:
    line: int = node.start_mark.line
    return line + 1


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def check_tree(root: yaml.Node, max_depth: int, max_nodes: int) -> None:
    """Expanded size and depth within bounds, no cycle, no duplicate key; iterative, so a long
    chain of aliases cannot exhaust the stack. Shared (aliased) nodes are measured once."""
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    open_nodes: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            kids = _children(node)
            size[key] = 1 + sum(size[id(k)] for k in kids)
            depth[key] = 1 + max((depth[id(k)] for k in kids), default=0)
            open_nodes.discard(key)
            if size[key] > max_nodes:
                raise Refused(
                    _line(node), f"more than {max_nodes} YAML nodes after expanding aliases"
                )
            if depth[key] > max_depth:
                raise Refused(_line(node), f"nesting deeper than {max_depth} levels (with aliases)")
            if isinstance(node, yaml.MappingNode):
                _no_duplicate_keys(node)
            elif isinstance(node, yaml.ScalarNode) and node.style is None:
                _no_odd_start(node)
            continue
        if key in size:
            continue
        if key in open_nodes:
            raise Refused(_line(node), "a recursive alias (an anchor used inside itself)")
        open_nodes.add(key)
        stack.append((node, True))
        stack.extend((kid, False) for kid in _children(node) if id(kid) not in size)


def _no_odd_start(node: yaml.ScalarNode) -> None:
    """A plain (unquoted) scalar that starts with an invisible space was meant to be indented."""
    if node.value[:1] and re.match(f"[{_ODD_SPACE}]", node.value[:1]):
        raise Refused(_line(node), _indent_message(node.value[0]), node.start_mark.column + 1)


def _no_duplicate_keys(node: yaml.MappingNode) -> None:
    seen: dict[tuple[str, str], int] = {}
    merges = [key for key, _value in node.value if key.tag == _MERGE_TAG]
    if len(merges) > 1:
        raise Refused(
            _line(merges[1]),
            f"duplicate merge key `<<` (first at line {_line(merges[0])}): merge several "
            "mappings with one key, `<<: [*a, *b]`",
            merges[1].start_mark.column + 1,
        )
    for key, _value in node.value:
        if not isinstance(key, yaml.ScalarNode) or key.tag == _MERGE_TAG:
            continue
        if key.tag == _BOOL_TAG and key.style is None:
            value = yaml.SafeLoader.bool_values.get(key.value.lower())
            raise Refused(
                _line(key),
                f"key `{key.value}` is not a name{boolean_hint(bool(value), key.value)}",
                key.start_mark.column + 1,
            )
        ident = (key.tag, key.value)
        if ident in seen:
            raise Refused(
                _line(key),
                f"duplicate key `{key.value}` (first at line {seen[ident]})",
                key.start_mark.column + 1,
            )
        seen[ident] = _line(key)


def _first_bad_value(root: yaml.Node, exc: BaseException) -> tuple[int, str]:
    """Line and message of the value a construction failure came from."""
    mark = getattr(exc, "problem_mark", None)
    if mark is not None:
        return mark.line + 1, f"bad value: {getattr(exc, 'problem', None) or exc}"
    loader = yaml.SafeLoader("")
    try:
        seen: set[int] = set()
        stack = [root]
        while stack:
            node = stack.pop()
            if id(node) in seen:
                continue
            seen.add(id(node))
            if isinstance(node, yaml.ScalarNode):
                try:
                    loader.construct_object(node)
                except Exception as bad:  # as in construct()
                    return _line(node), f"bad value for tag `{node.tag}`: {_short(bad)}"
            stack.extend(reversed(_children(node)))
    finally:
        loader.dispose()
    return _line(root), f"bad value: {_short(exc)}"


def _short(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."
