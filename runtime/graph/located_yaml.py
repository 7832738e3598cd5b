"""A safe YAML reader that keeps the source location of every mapping key, value and list item.

Guards against hostile input: files over ``MAX_BYTES``, bytes that are not UTF-8, nesting deeper
than ``MAX_DEPTH``, and alias ("billion laughs") expansion beyond ``MAX_NODES``. Every failure is a
:class:`~umbra.connectors.errors.CheckFailed` with ``FILE:LINE:COL``; nothing else escapes.
Positions, line ends, indentation and merge keys follow :mod:`umbra.connectors.safe_yaml`: a key
merged in by ``<<: *anchor`` keeps the location where the anchor's mapping writes it.

A mapping or list tagged ``!replace`` is read as an untagged one with ``replace`` set: a graph
that extends another replaces the base's value with it instead of merging
(``umbra.runtime.graph.parse_extends``).
"""

from __future__ import annotations

from typing import Any

import yaml

from umbra.connectors.errors import CheckFailed, Diagnostic, Location
from umbra.connectors.safe_yaml import (
    BoundedLoader,
    Refused,
    check_tree,
    line_end_problem,
    odd_indent,
)

MAX_BYTES = 1_000_000
MAX_DEPTH = 64
MAX_NODES = 100_000
_PLAIN_TAGS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq")
_MERGE_TAG = "tag:yaml.org,2002:merge"
REPLACE_TAG = "!replace"


class YMap(dict[Any, Any]):
    """A mapping with the location of itself, of each key and of each value."""

    loc: Location
    key_loc: dict[Any, Location]
    val_loc: dict[Any, Location]
    replace: bool = False


class YList(list[Any]):
    """A list with the location of itself and of each item."""

    loc: Location
    item_loc: list[Location]
    replace: bool = False


def _loc(file: str, node: yaml.Node) -> Location:
    mark = node.start_mark
    return Location(file, mark.line + 1, mark.column + 1)


class _Builder:
    def __init__(self, file: str) -> None:
        self.file = file
        self.nodes = 0
        self.constructor = yaml.SafeLoader("")  # only its scalar constructors are used

    def build(self, node: yaml.Node, depth: int = 0) -> Any:
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise _TooBig(node, f"more than {MAX_NODES} YAML nodes (after expanding aliases)")
        if depth > MAX_DEPTH:
            raise _TooBig(node, f"nesting deeper than {MAX_DEPTH} levels")
        collection = isinstance(node, yaml.MappingNode | yaml.SequenceNode)
        if collection and node.tag not in (*_PLAIN_TAGS, REPLACE_TAG):
            raise _Bad(node, f"unsupported YAML tag `{node.tag}`")
        if isinstance(node, yaml.MappingNode):
            out = self.mapping(node, depth)
            out.replace = node.tag == REPLACE_TAG
            return out
        if isinstance(node, yaml.SequenceNode):
            items = YList()
            items.loc, items.item_loc = _loc(self.file, node), []
            items.replace = node.tag == REPLACE_TAG
            for item in node.value:
                items.append(self.build(item, depth + 1))
                items.item_loc.append(_loc(self.file, item))
            return items
        try:
            return self.constructor.construct_object(node, deep=True)
        except yaml.YAMLError as exc:
            raise _Bad(node, f"bad value: {_problem(exc)}") from None
        except Exception as exc:  # `!!float abc`, a 5000-digit integer: the file's fault
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise _Bad(node, f"bad value for tag `{node.tag}`: {text[:160]}") from None

    def mapping(self, node: yaml.MappingNode, depth: int) -> YMap:
        """A mapping with YAML 1.1 merges: ``<<`` takes a mapping or a list of mappings; the
        mapping's own keys override merged ones, and an earlier merged mapping wins over a later
        one. Its own keys are unique (``check_tree`` refused duplicates before)."""
        out = YMap()
        out.loc, out.key_loc, out.val_loc = _loc(self.file, node), {}, {}
        own = []
        for key_node, value_node in node.value:
            if key_node.tag == _MERGE_TAG:
                for merged in self.merged(value_node, depth):
                    for key in merged:
                        if key not in out:
                            out[key] = merged[key]
                            out.key_loc[key] = merged.key_loc[key]
                            out.val_loc[key] = merged.val_loc[key]
            else:
                own.append((key_node, value_node))
        own_keys: set[Any] = set()
        for key_node, value_node in own:
            key = self.build(key_node, depth + 1)
            if isinstance(key, dict | list):
                raise _Bad(key_node, "a mapping key must be a plain value")
            if key in own_keys:  # `1` and `0x1`: two spellings, one key
                first = out.key_loc[key]
                raise _Bad(key_node, f"duplicate key `{key}` (first at line {first.line})")
            own_keys.add(key)
            out[key] = self.build(value_node, depth + 1)
            out.key_loc[key] = _loc(self.file, key_node)
            out.val_loc[key] = _loc(self.file, value_node)
        return out

    def merged(self, node: yaml.Node, depth: int) -> list[YMap]:
        """The mappings a ``<<`` value names, in order."""
        nodes = node.value if isinstance(node, yaml.SequenceNode) else [node]
        out = []
        for item in nodes:
            if not isinstance(item, yaml.MappingNode):
                raise _Bad(
                    item,
                    "bad merge: `<<` takes a mapping or a list of mappings (`<<: *base`, "
                    f"`<<: [*a, *b]`), found {_node_kind(item)}",
                )
            out.append(self.build(item, depth + 1))
        return out


def _node_kind(node: yaml.Node) -> str:
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    return f"`{node.value}`" if isinstance(node, yaml.ScalarNode) else "a node"


class _Bad(Exception):
    def __init__(self, node: yaml.Node, message: str) -> None:
        self.node, self.message = node, message


class _TooBig(_Bad):
    pass


def _problem(exc: yaml.YAMLError) -> str:
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return str(problem)


def load_located(text_or_bytes: str | bytes, file: str) -> Any:
    """One YAML document as YMap/YList/scalars with locations; CheckFailed on any problem."""

    def fail(line: int, col: int, message: str) -> CheckFailed:
        return CheckFailed([Diagnostic(Location(file, line, col), message)])

    if isinstance(text_or_bytes, bytes):
        if len(text_or_bytes) > MAX_BYTES:
            raise fail(
                1, 1, f"file is {len(text_or_bytes)} bytes; a graph file is at most {MAX_BYTES}"
            )
        try:
            text = text_or_bytes.decode("utf-8")
        except UnicodeDecodeError as exc:
            line = text_or_bytes[: exc.start].count(b"\n") + 1
            raise fail(
                line, 1, f"not UTF-8 text (byte {exc.start} is 0x{text_or_bytes[exc.start]:02x})"
            ) from None
    else:
        text = text_or_bytes
        if len(text) > MAX_BYTES:
            raise fail(1, 1, f"file is {len(text)} characters; a graph file is at most {MAX_BYTES}")
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise fail(line, 1, "not a text file (contains a NUL byte)")
    text = text.removeprefix("\ufeff")  # a byte-order mark is no character of line 1
    odd = line_end_problem(text)
    if odd is not None:
        raise fail(odd.line, odd.column, odd.message)
    try:
        loader = BoundedLoader(text, MAX_DEPTH)
        try:
            node = loader.get_single_node()
            if node is not None:  # alias bombs and cycles, measured without expanding them
                check_tree(node, MAX_DEPTH, MAX_NODES)
        finally:
            loader.dispose()
    except Refused as exc:
        raise fail(exc.line, exc.column, exc.message) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        indent = odd_indent(text, line)
        if indent is not None:
            raise fail(indent.line, indent.column, f"YAML syntax: {indent.message}") from None
        raise fail(line, col, f"YAML syntax: {exc.problem or exc.context}") from None
    except yaml.YAMLError as exc:
        raise fail(1, 1, f"YAML: {_problem(exc)}") from None
    except RecursionError:
        raise fail(1, 1, "YAML nesting is too deep") from None
    except Exception as exc:  # PyYAML itself failing on the text (`%YAML 1.<5000 digits>`)
        text_of_exc = (str(exc).splitlines() or [type(exc).__name__])[0][:160]
        raise fail(1, 1, f"YAML syntax: {text_of_exc}") from None
    if node is None:
        return None
    builder = _Builder(file)
    try:
        return builder.build(node)
    except _Bad as exc:
        loc = _loc(file, exc.node)
        raise fail(loc.line, loc.column, exc.message) from None
    except RecursionError:
        raise fail(1, 1, "YAML nesting is too deep") from None
