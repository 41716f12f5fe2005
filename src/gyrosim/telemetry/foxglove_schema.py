"""Does Foxglove's JSON-schema reader accept a schema? The rules of its ``parseJsonSchema``, in Python.

Foxglove (the app, and its open-source ancestors Foxglove Studio and Lichtblick) turns the ``jsonschema`` of a
JSON channel into message definitions with ``parseJsonSchema`` and drops the whole channel when that throws.
It walks the schema from the root:

* every object (the root, a nested object field, the items of an array of objects) has ``"type": "object"``
  and a ``properties`` object (without it the reader throws);
* every field has exactly one ``type`` name out of ``boolean``, ``string``, ``number``, ``integer``,
  ``object``, ``array``; a list of names (``["number", "null"]``), ``"null"`` or no type at all throw;
* a string has no ``contentEncoding`` or ``"base64"``;
* an array has ``items`` with one of ``boolean``, ``string`` (no ``contentEncoding``), ``number``,
  ``integer``, ``object`` (no arrays of arrays);
* a field with ``oneOf`` is an enumeration whose alternatives all carry a numeric ``const``.

A message may still carry ``null`` in any field: the reader does not check values against the schema.

Examples
--------
>>> check_foxglove_schema({"type": "object", "properties": {"x": {"type": ["number", "null"]}}})
['x: type must be one name, got ["number", "null"]']
>>> check_foxglove_schema({"type": "object", "properties": {"x": {"type": "number"}}})
[]
"""

from __future__ import annotations

import json

__all__ = ["check_foxglove_schema", "check_foxglove_schema_data"]

_SCALARS = ("boolean", "string", "number", "integer")


def check_foxglove_schema(schema: dict, name: str = "") -> list[str]:
    """Every reason Foxglove's JSON-schema reader would refuse ``schema`` (empty: it is accepted).

    Parameters
    ----------
    schema : dict
        The JSON Schema of a channel (its root describes the message object).
    name : str
        Prefix of the field paths in the messages (e.g. the schema name); default none.

    Returns
    -------
    list of str
        ``"<field path>: <problem>"`` for each problem found.
    """
    problems: list[str] = []
    _object(schema, name, problems)
    return problems


def check_foxglove_schema_data(data: bytes | str, name: str = "") -> list[str]:
    """:func:`check_foxglove_schema` of a schema as stored in an MCAP Schema record (UTF-8 JSON)."""
    try:
        schema = json.loads(data)
    except ValueError as e:
        return [f"{name or '(root)'}: not JSON ({e})"]
    if not isinstance(schema, dict):
        return [f"{name or '(root)'}: not a JSON object"]
    return check_foxglove_schema(schema, name)


def _where(path: str) -> str:
    return path or "(root)"


def _object(schema, path: str, problems: list[str]) -> None:
    if not isinstance(schema, dict):
        problems.append(f"{_where(path)}: schema must be an object, got {json.dumps(schema)}")
        return
    if schema.get("type") != "object":
        problems.append(f"{_where(path)}: expected \"type\": \"object\", got {json.dumps(schema.get('type'))}")
        return
    props = schema.get("properties")
    if not isinstance(props, dict):
        problems.append(f"{_where(path)}: an object needs \"properties\" (Foxglove throws without them)")
        return
    for field, sub in props.items():
        _field(sub, f"{path}.{field}" if path else field, problems)


def _field(schema, path: str, problems: list[str]) -> None:
    if not isinstance(schema, dict):
        problems.append(f"{path}: schema must be an object, got {json.dumps(schema)}")
        return
    if isinstance(schema.get("oneOf"), list):
        if not all(isinstance(a, dict) and isinstance(a.get("const"), (int, float))
                   and not isinstance(a.get("const"), bool) for a in schema["oneOf"]):
            problems.append(f"{path}: oneOf alternatives must all have a number const")
        return
    t = schema.get("type")
    if isinstance(t, list):
        problems.append(f"{path}: type must be one name, got {json.dumps(t)}")
        return
    if t in ("boolean", "number", "integer"):
        return
    if t == "string":
        if schema.get("contentEncoding") not in (None, "base64"):
            problems.append(f"{path}: unsupported contentEncoding {json.dumps(schema['contentEncoding'])}")
        return
    if t == "object":
        _object(schema, path, problems)
        return
    if t == "array":
        items = schema.get("items")
        it = items.get("type") if isinstance(items, dict) else None
        if it == "object":
            _object(items, path + "[]", problems)
        elif it == "string" and items.get("contentEncoding") is not None:
            problems.append(f"{path}[]: array items of type string take no contentEncoding")
        elif it not in _SCALARS:
            problems.append(f"{path}[]: array items need one type out of {', '.join(_SCALARS)}, object; "
                            f"got {json.dumps(it)}")
        return
    problems.append(f"{path}: unsupported type {json.dumps(t)} (one of {', '.join(_SCALARS)}, object, array)")
