"""What Foxglove and Lichtblick make of a JSON schema: the rules of their ``parseJsonSchema``
(``packages/mcap-support/src/parseJsonSchema.ts`` in foxglove/studio and in
Lichtblick-Suite/lichtblick), restated in Python to test against: a schema it cannot read makes the
viewer refuse the whole channel."""

from __future__ import annotations

from typing import Any

PRIMITIVES = {"boolean": "bool", "number": "float64", "integer": "uint32"}


def viewer_datatypes(schema: dict[str, Any], name: str) -> dict[str, dict[str, str]]:
    """Datatypes (type name -> field -> type) the viewer derives; ValueError where it throws."""
    out: dict[str, dict[str, str]] = {}

    def walk(node: dict[str, Any], type_name: str) -> None:
        if node.get("type") != "object":
            raise ValueError(f'{type_name}: expected "type": "object", got {node.get("type")!r}')
        if not isinstance(node.get("properties"), dict):
            raise ValueError(f"{type_name}: an object needs `properties` (Object.entries)")
        fields: dict[str, str] = {}
        for field, sub in node["properties"].items():
            if not isinstance(sub, dict):
                raise ValueError(f"{type_name}.{field}: a property's schema is an object")
            if isinstance(sub.get("oneOf"), list):
                if not all(isinstance(alt.get("const"), (int, float)) for alt in sub["oneOf"]):
                    raise ValueError(f"{type_name}.{field}: oneOf alternatives must be numbers")
                fields[field] = "uint32"
                continue
            kind = sub.get("type")
            if not isinstance(kind, str):  # a list of types, or none
                raise ValueError(f"{type_name}.{field}: unsupported type {kind!r}")
            if kind in PRIMITIVES:
                fields[field] = PRIMITIVES[kind]
            elif kind == "string":
                if sub.get("contentEncoding") not in (None, "base64"):
                    raise ValueError(f"{type_name}.{field}: unsupported contentEncoding")
                fields[field] = "string" if sub.get("contentEncoding") is None else "uint8[]"
            elif kind == "object":
                walk(sub, f"{type_name}.{field}")
                fields[field] = f"{type_name}.{field}"
            elif kind == "array":
                items = sub.get("items")
                if not isinstance(items, dict):
                    raise ValueError(f"{type_name}.{field}: an array needs `items` (items.type)")
                item = items.get("type")
                if isinstance(item, str) and item in PRIMITIVES:
                    fields[field] = PRIMITIVES[item] + "[]"
                elif item == "string" and items.get("contentEncoding") is None:
                    fields[field] = "string[]"
                elif item == "object":
                    walk(items, f"{type_name}.{field}")
                    fields[field] = f"{type_name}.{field}[]"
                else:
                    raise ValueError(f"{type_name}.{field}: unsupported array item type {item!r}")
            else:
                raise ValueError(f"{type_name}.{field}: unsupported type {kind!r}")
        out[type_name] = fields

    walk(schema, name)
    return out
